"""core.provenance.import_closure / closure_sha256: the code a pipeline rule can execute, found statically.

A rule's ``source`` param is the hash of the import closure of what it runs, so a change reruns
exactly the rules whose code it touches. Checked on a synthetic package whose closure is known,
on the real package against a second route (a full :func:`ast.parse` of every file), and by what
the pipeline's rules are given.
"""

from __future__ import annotations

import ast
import shutil
from pathlib import Path

import pytest

from pose_uncertainty.core import provenance
from pose_uncertainty.core.provenance import closure_sha256, import_closure, imports_of

PACKAGE = Path(provenance.__file__).resolve().parents[1]
ROOT = PACKAGE.parent
SCRIPTS = Path(__file__).resolve().parents[1] / "workflow" / "scripts"


def _write(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text, encoding="utf-8")
    return root


#: a package ``pkg`` with every way of importing: absolute, relative (one and two dots), ``from . import``,
#: inside a function, parenthesised over lines, a module named in a string, and modules nobody imports
SYNTHETIC = {
    "pkg/__init__.py": '"""top."""\n',
    "pkg/a/__init__.py": "from .b import f  # the package runs its own imports\n",
    "pkg/a/b.py": "import os\nimport numpy as np\n\ndef f():\n    return 1\n",
    "pkg/a/c.py": (
        "from __future__ import annotations\n"
        "from ..d import (\n    e,\n    g,\n)\n"
        "from . import b\n"
        "\n\ndef lazy():\n    import pkg.h.i\n    from pkg.k import z  # z is a name, not a module\n    return z\n"
    ),
    "pkg/d/__init__.py": "",
    "pkg/d/e.py": "X = 1\n",
    "pkg/d/g.py": "import importlib\nMOD = importlib.import_module('pkg.j')\n",
    "pkg/h/__init__.py": "",
    "pkg/h/i.py": "",
    "pkg/j.py": '"""Named in a docstring only: pkg.m is no import, nor is the word from here import there."""\n',
    "pkg/k.py": "z = 2\n",
    "pkg/m.py": "import pkg.a.c  # imports the other way: not in c's closure\n",
    "pkg/unused.py": "import pkg.a.c\n",
}


def test_synthetic_closure_is_exact(tmp_path: Path):
    root = _write(tmp_path, SYNTHETIC)
    assert import_closure("pkg.a.c", root=root) == (
        "pkg", "pkg.a", "pkg.a.b", "pkg.a.c", "pkg.d", "pkg.d.e", "pkg.d.g", "pkg.h", "pkg.h.i", "pkg.j", "pkg.k",
    )  # fmt: skip
    assert import_closure("pkg.a.b", root=root) == ("pkg", "pkg.a", "pkg.a.b")  # a.__init__ runs first
    assert import_closure("pkg.a.b.f", root=root) == import_closure("pkg.a.b", root=root)  # a name: its module
    assert import_closure("pkg.m", root=root) == tuple(sorted({"pkg.m", *import_closure("pkg.a.c", root=root)}))


def test_synthetic_hash_follows_exactly_the_closure(tmp_path: Path):
    root = _write(tmp_path / "one", SYNTHETIC)
    before = closure_sha256("pkg.a.c", root=root)
    (root / "pkg/m.py").write_text("# changed\n", encoding="utf-8")  # outside the closure
    (root / "pkg/unused.py").unlink()
    assert closure_sha256("pkg.a.c", root=root) == before
    copy = shutil.copytree(root, tmp_path / "two")  # where the tree lies does not count
    assert closure_sha256("pkg.a.c", root=copy) == before
    with (root / "pkg/h/i.py").open("a", encoding="utf-8") as f:  # reached only through a lazy import
        f.write("# a comment\n")
    assert closure_sha256("pkg.a.c", root=root) != before
    assert closure_sha256("pkg.a.c", root=copy) == before
    (copy / "data.txt").write_text("v1", encoding="utf-8")
    with_data = closure_sha256("pkg.a.c", root=copy, data=("data.txt",))
    assert with_data != before
    (copy / "data.txt").write_text("v2", encoding="utf-8")
    assert closure_sha256("pkg.a.c", root=copy, data=("data.txt",)) != with_data


def test_an_unknown_module_is_one_line_naming_it(tmp_path: Path):
    root = _write(tmp_path, SYNTHETIC)
    with pytest.raises(ValueError, match=r"'pkg\.nope\.x'.*pkg/nope/x\.py"):
        import_closure("pkg.nope.x", root=root)


def _imports_by_ast(path: Path) -> set[str]:
    """The second route: every import node of the whole file's syntax tree, resolved as Python does."""
    own = list(path.relative_to(ROOT).parts[:-1])
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_bytes())):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            up = own[: len(own) - node.level + 1]
            base = ".".join([*up, node.module or ""]).strip(".") if node.level else node.module
            names.add(base)
            names.update(f"{base}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            names.add(node.value)
    return names


def _closure_by_ast(*modules: str) -> tuple[str, ...]:
    files = {".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__"): p
             for p in PACKAGE.rglob("*.py")}  # fmt: skip
    found: set[str] = set()
    todo = list(modules)
    while todo:
        name = todo.pop()
        if name in found or not name.startswith("pose_uncertainty"):
            continue
        if name not in files:
            todo.append(name.rpartition(".")[0])
            continue
        found.add(name)
        todo.extend(".".join(name.split(".")[:i]) for i in range(1, name.count(".") + 1))
        todo.extend(_imports_by_ast(files[name]))
    return tuple(sorted(found))


@pytest.mark.parametrize("module", ["pose_uncertainty.cli.job", "pose_uncertainty.pipeline.claims",
                                    "pose_uncertainty.present.report", "pose_uncertainty.present.pipeline_figures"])
def test_real_closures_agree_with_a_full_syntax_tree_walk(module: str):
    assert import_closure(module) == _closure_by_ast(module)


def test_the_claims_closure_holds_the_claims_and_not_the_runs():
    claims = import_closure("pose_uncertainty.pipeline.claims")
    assert {"pose_uncertainty", "pose_uncertainty.pipeline", "pose_uncertainty.pipeline.claims"} <= set(claims)
    assert "pose_uncertainty.records.run" not in claims
    assert not [m for m in claims if m.startswith(("pose_uncertainty.present", "pose_uncertainty.methods"))]
    job = import_closure("pose_uncertainty.cli.job")  # a run: its lazily imported pipeline.jobs and beyond
    assert {"pose_uncertainty.pipeline.jobs", "pose_uncertainty.records.run", "pose_uncertainty.experiments.run",
            "pose_uncertainty.core.se2"} <= set(job)
    assert "pose_uncertainty.pipeline.claims" not in job
    assert not [m for m in job if m.startswith("pose_uncertainty.present")]


def test_every_workflow_script_imports_package_modules_that_exist():
    for script in sorted(SCRIPTS.glob("*.py")):
        names = imports_of(script)
        assert names, script.name  # each script runs package code: its rule's source is not empty
        assert import_closure(*names)  # raises on a name that resolves to no module
    assert imports_of(SCRIPTS / "evaluate_claims.py") == (
        "pose_uncertainty.pipeline.claims", "pose_uncertainty.pipeline.claims.ClaimDataError",
        "pose_uncertainty.pipeline.claims.write_claims")
