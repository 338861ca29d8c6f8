"""Every word of the product resolves for a reader who has only the repository.

The source documents are cited by author and year (Němec 2012, Šafránek 2022,
Skalka 2011, Kulich 2014, the Russian lecture deck on motion models; README.md,
"Sources"), never by the numbers of a private file list ("seed 001", "thesis 002",
"deck 004"); the word "seed" means a random seed only. Nothing cites the project's
internal specification ("SPEC §3.2") or its tracker ("issue 11"): a reader has
neither.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: What a reader of the repository gets: the package, the pipeline, its configs, the docs.
PRODUCT = ("src", "workflow", "config", "notebooks", "benchmarks", "docs", "README.md", "Snakefile", "Makefile")

#: Words that point outside the repository, each with what to write instead.
FORBIDDEN = {
    "a source document by number (cite author and year)": re.compile(
        r"\b(?:seed|thesis|theses|deck|decks|lecture)s?[ -]00\d", re.IGNORECASE),
    "the internal specification (cite the source or the module)": re.compile(r"SPEC §|\bSPEC\b"),
    "the internal tracker (say what it names)": re.compile(r"\bissues? #?\d+\b", re.IGNORECASE),
}

#: Generated or cached (git-ignored): not part of the product's text.
_SKIP_DIRS = {"__pycache__", ".ipynb_checkpoints", ".pytest_cache", ".ruff_cache", ".mypy_cache", "build",
              "_build", "generated",  # docs/_build, docs/reference/generated: built from the sources
              "node_modules"}  # node_modules: the benchmark's npm tools (git-ignored)
_SKIP_UNDER = (Path("benchmarks", "results"),)


def _skipped(rel: Path) -> bool:
    return (bool(_SKIP_DIRS & set(rel.parts)) or any(part.endswith(".egg-info") for part in rel.parts)
            or any(rel.is_relative_to(under) for under in _SKIP_UNDER))


def _product_files(root: Path) -> list[Path]:
    files = []
    for name in PRODUCT:
        top = root / name
        if top.is_file():
            files.append(top)
        elif top.is_dir():
            files.extend(p for p in sorted(top.rglob("*"))
                         if p.is_file() and not _skipped(p.relative_to(root)))
    return files


def _text(path: Path) -> str | None:
    try:
        text = path.read_text(encoding="utf-8")
    except (UnicodeDecodeError, OSError):
        return None  # binary (a log, an image): no words
    return None if "\x00" in text else text


def find_forbidden_words(root: Path = ROOT) -> list[str]:
    """``file:line: kind: the line`` for every forbidden word under ``root``'s product."""
    hits = []
    for path in _product_files(root):
        text = _text(path)
        if text is None:
            continue
        for number, line in enumerate(text.splitlines(), 1):
            for kind, pattern in FORBIDDEN.items():
                if pattern.search(line):
                    hits.append(f"{path.relative_to(root)}:{number}: {kind}: {line.strip()[:120]}")
    return hits


def test_the_product_cites_only_what_a_reader_can_look_up() -> None:
    hits = find_forbidden_words()
    assert not hits, f"{len(hits)} word(s) a reader cannot resolve:\n" + "\n".join(hits)


def test_the_scan_finds_each_kind_and_spares_identifiers(tmp_path: Path) -> None:
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "m.py").write_text(
        "# Seed 001's chassis\n"                      # 1: a source by number
        "_SPECTRA_BATCH_BYTES = 1  # SPEC_JSON\n"     # 2: identifiers, not words
        "x = 1  # SPEC §3.2\n"                        # 3: the specification
        "y = 2  # Method C (issue 11)\n"              # 4: the tracker
        "rng = default_rng(seed=3)  # a random seed\n",  # 5: fine
        encoding="utf-8")
    (tmp_path / "README.md").write_text("the lecture decks 003/004\n", encoding="utf-8")
    hits = find_forbidden_words(tmp_path)
    assert [h.split(":")[:2] for h in hits] == [["src/m.py", "1"], ["src/m.py", "3"], ["src/m.py", "4"],
                                                 ["README.md", "1"]]
