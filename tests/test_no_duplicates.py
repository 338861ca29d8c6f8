"""One of each helper: a scan of src/ for helpers written twice.

Two checks over every module of the package:

* a private (``_name``) module-level function is defined in one module only — the same
  private helper in two modules is a copy (public functions of parallel APIs, such as each
  method's ``propagate``, are exempt: one name, one contract, several implementations);
* no two functions of three or more statements have the same body up to names, constants
  and annotations (a structural copy under another name).
"""

from __future__ import annotations

import ast
import hashlib
from collections import defaultdict
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "src" / "pose_uncertainty"


class _Normalise(ast.NodeTransformer):
    """Replace every name, attribute, argument and constant by a placeholder."""

    def visit_Name(self, node: ast.Name) -> ast.AST:
        return ast.copy_location(ast.Name(id="_", ctx=node.ctx), node)

    def visit_arg(self, node: ast.arg) -> ast.AST:
        node.arg, node.annotation = "_", None
        return node

    def visit_Constant(self, node: ast.Constant) -> ast.AST:
        return ast.copy_location(ast.Constant(value=0), node)

    def visit_Attribute(self, node: ast.Attribute) -> ast.AST:
        self.generic_visit(node)
        node.attr = "_"
        return node


def _shape(fn: ast.FunctionDef) -> str | None:
    """A hash of the function body up to names and constants; None for bodies under 3 statements."""
    body = [s for s in fn.body if not (isinstance(s, ast.Expr) and isinstance(s.value, ast.Constant))]
    if len(body) < 3:
        return None
    tree = ast.parse("\n".join(ast.unparse(s) for s in body))
    return hashlib.sha256(ast.dump(_Normalise().visit(tree)).encode()).hexdigest()


def scan(sources: dict[str, str]) -> list[str]:
    """Every repeated helper in ``{module path: source}``, one line each."""
    private: dict[str, list[str]] = defaultdict(list)
    shapes: dict[str, list[str]] = defaultdict(list)
    for path, text in sorted(sources.items()):
        tree = ast.parse(text)
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and node.name.startswith("_") and not node.name.startswith("__"):
                private[node.name].append(path)
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef) and (h := _shape(node)) is not None:
                shapes[h].append(f"{path}:{node.lineno} {node.name}")
    out = [f"private helper {n} defined in {', '.join(ps)}" for n, ps in private.items() if len(ps) > 1]
    out += [f"same body: {' ~ '.join(fs)}" for fs in shapes.values() if len(fs) > 1]
    return out


def test_src_has_no_repeated_helper():
    sources = {str(p.relative_to(PKG)): p.read_text(encoding="utf-8") for p in PKG.rglob("*.py")}
    assert scan(sources) == []


def test_the_scan_finds_both_kinds_of_copy():
    # the check itself must be able to fail
    helper = "def _frame(t):\n    c = cos(t)\n    s = sin(t)\n    return [[c, s], [-s, c]]\n"
    renamed = "def rotation(a):\n    u = cos(a)\n    v = sin(a)\n    return [[u, v], [-v, u]]\n"
    found = scan({"a.py": helper, "b.py": helper, "c.py": renamed})
    assert "private helper _frame defined in a.py, b.py" in found
    assert any(line.startswith("same body:") and "c.py:1 rotation" in line for line in found)
    assert scan({"a.py": helper}) == []
