"""bench/'s scripts are thin callers of ``loosefit``: none imports another.

A measure two scripts share lives in the package (``loosefit.eval``), where it is tested;
a script run as ``python bench/<group>/<script>.py`` has only its own folder on the path,
so an import of a sibling script by its bare name would also break when scripts move.
"""

from __future__ import annotations

import ast
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "bench"


def imported_modules(tree: ast.AST) -> list[tuple[int, str]]:
    """(line, top-level name) of every absolute import in a module, however deep."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name.split(".")[0]) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # a relative import can only reach a sibling
                found.append((node.lineno, "." * node.level + (node.module or "")))
            elif node.module:
                found.append((node.lineno, node.module.split(".")[0]))
    return found


def script_imports(scripts: dict[str, str]) -> list[str]:
    """``path:line name`` for every import, in the scripts ``path -> source``, of a bench
    script or of bench/ itself."""
    names = {Path(path).stem for path in scripts} | {"bench"}
    broken = []
    for path, text in sorted(scripts.items()):
        for line, name in imported_modules(ast.parse(text, filename=path)):
            if name in names or name.startswith("."):
                broken.append(f"{path}:{line} {name}")
    return broken


def test_no_bench_script_imports_another() -> None:
    scripts = {
        path.relative_to(BENCH.parent).as_posix(): path.read_text(encoding="utf-8")
        for path in sorted(BENCH.rglob("*.py"))
    }
    assert len(scripts) > 20, f"no scripts under {BENCH}"
    broken = script_imports(scripts)
    assert not broken, "move what these share into loosefit:\n" + "\n".join(broken)


def test_the_check_finds_every_kind_of_import() -> None:
    scripts = {
        "bench/a/one.py": "import numpy\nfrom loosefit.eval import depth\n",
        "bench/b/two.py": "def f():\n    from one import g\n",
        "bench/b/three.py": "import two as t\nfrom . import one\nfrom bench.a import one\n",
    }
    assert script_imports(scripts) == [
        "bench/b/three.py:1 two",
        "bench/b/three.py:2 .",
        "bench/b/three.py:3 bench",
        "bench/b/two.py:2 one",
    ]


def test_every_script_sits_in_a_group() -> None:
    groups = {"speed", "quality", "ablations", "data"}
    loose = [
        path.relative_to(BENCH).as_posix()
        for path in BENCH.rglob("*.py")
        if path.relative_to(BENCH).parts[0] not in groups
    ]
    assert not loose, f"scripts outside {sorted(groups)}: {loose}"
