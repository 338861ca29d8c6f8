"""The package's folders are its layers; a lower layer never imports a higher one.

Layers, lowest first: ``core`` (validation, kinematics, trajectories, noise, statistics,
provenance) ← ``methods`` (covariance, exponential coordinates, motion models, maps, Monte
Carlo) ← ``localization`` (worlds, sensors, Bayes filters) ← ``analysis`` (measures, accuracy,
calibration, studies) ← ``robot`` (a real robot's bags: calibration, nav2 parameters)
← ``experiments`` (configuration, sweeps, execution, cost) ← ``records`` (the log formats)
← ``pipeline`` (job entry points, tables, summaries, claims) ← ``present`` (figures, report)
← ``cli``. Every import is checked, at module top or not.
"""

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "src" / "pose_uncertainty"
LAYERS = ("core", "methods", "localization", "analysis", "robot", "experiments", "records", "pipeline", "present", "cli")


def _layer_of(parts: tuple[str, ...]) -> str | None:
    """Layer of a module given its dotted path inside the package (None: the package root)."""
    if not parts:
        return None
    head = parts[0].removesuffix(".py")
    return head if head in LAYERS else None


def _imports(path: Path, root: Path = PKG) -> list[tuple[int, tuple[str, ...]]]:
    """(line, target module path inside pose_uncertainty) of every import of the package (``path``
    a module below ``root``, the package's folder)."""
    rel = path.relative_to(root).with_suffix("").parts  # e.g. ("methods", "maps")
    here = rel[:-1]
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = here[: len(here) - (node.level - 1)] if node.level > 1 else here
                mod = tuple(node.module.split(".")) if node.module else ()
                targets = [base + mod] if node.module else [(*base, a.name) for a in node.names]
            elif node.module and node.module.split(".")[0] == "pose_uncertainty":
                mod = tuple(node.module.split(".")[1:])
                targets = [mod] if mod else [(a.name,) for a in node.names]
            else:
                continue
            out.extend((node.lineno, t) for t in targets)
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == "pose_uncertainty":
                    out.append((node.lineno, tuple(a.name.split(".")[1:])))
    return out


def _modules() -> list[Path]:
    return sorted(p for p in PKG.rglob("*.py"))


def test_every_module_sits_in_a_layer():
    loose = [
        str(p.relative_to(PKG))
        for p in _modules()
        if p.parent == PKG and p.name not in ("__init__.py", "cli.py")
    ]
    assert loose == [], f"modules outside the layer folders {LAYERS}: {loose}"


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PKG)))
def test_no_import_of_a_higher_layer(path):
    mine = _layer_of(path.relative_to(PKG).parts)
    if mine is None:
        return  # the package's __init__: version only
    rank = LAYERS.index(mine)
    bad = []
    for line, target in _imports(path):
        theirs = _layer_of(target)
        if theirs is not None and LAYERS.index(theirs) > rank:
            bad.append(f"line {line}: {mine} imports {'.'.join(target)} ({theirs})")
    assert bad == [], "\n".join(bad)


def test_the_checker_sees_a_violation(tmp_path):
    # the check itself must be able to fail: a core module importing present is caught
    # (in a folder of its own: the package's folder is read by tests running at the same time, pytest -n)
    fake = tmp_path / "pose_uncertainty" / "core" / "_layer_probe_tmp.py"
    fake.parent.mkdir(parents=True)
    fake.write_text("from ..present import report\nfrom pose_uncertainty.records import run\n")
    targets = [t for _, t in _imports(fake, tmp_path / "pose_uncertainty")]
    assert [_layer_of(t) for t in targets] == ["present", "records"]
