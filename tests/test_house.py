"""The house rules: no module of src/loosefit over 600 lines, no function over 120, and no
function taking more than 6 positional parameters.

A function's length is ``end_lineno - lineno + 1`` from :mod:`ast` (its docstring
included); a module's is its number of lines. Its positional parameters are its
positional-only and ordinary ones, a method's leading ``self`` or ``cls`` not counted;
the rest must be keyword-only (after ``*``). Warp kernels and functions
(``@wp.kernel``, ``@wp.func``, also spelt ``warp.``), whose arguments warp passes by
position, are exempt, and so is a module's ``forward`` method: ``torch.onnx.export`` passes
the graph's inputs to it by position, in the order of the graph's inputs.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "loosefit"
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 120
MAX_POSITIONAL = 6
WARP_DECORATORS = {"wp.kernel", "wp.func", "warp.kernel", "warp.func"}


def too_long(text: str, where: str) -> list[str]:
    """What in one module's ``text`` breaks the rules, as ``where:line name, length``."""
    out = []
    lines = len(text.splitlines())
    if lines > MAX_MODULE_LINES:
        out.append(f"{where}: the module, {lines} lines (at most {MAX_MODULE_LINES})")
    for node in ast.walk(ast.parse(text, filename=where)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            length = node.end_lineno - node.lineno + 1
            if length > MAX_FUNCTION_LINES:
                out.append(
                    f"{where}:{node.lineno} {node.name}, {length} lines "
                    f"(at most {MAX_FUNCTION_LINES})"
                )
    return out


def _is_warp(node: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """A warp kernel or function: decorated ``@wp.kernel``, ``@wp.func`` (or called so)."""
    for decorator in node.decorator_list:
        target = decorator.func if isinstance(decorator, ast.Call) else decorator
        if ast.unparse(target) in WARP_DECORATORS:
            return True
    return False


def too_many_positional(text: str, where: str) -> list[str]:
    """The functions in one module's ``text`` that take more than :data:`MAX_POSITIONAL`
    positional parameters, as ``where:line name, count``."""
    out = []
    for node in ast.walk(ast.parse(text, filename=where)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and not _is_warp(node):
            if node.name == "forward" and node.args.args and node.args.args[0].arg == "self":
                continue  # an nn.Module's forward: traced with its inputs by position
            params = node.args.posonlyargs + node.args.args
            count = len(params) - (bool(params) and params[0].arg in ("self", "cls"))
            if count > MAX_POSITIONAL:
                out.append((node.lineno, node.name, count))
    return [
        f"{where}:{line} {name}, {count} positional parameters "
        f"(at most {MAX_POSITIONAL}; make the rest keyword-only)"
        for line, name, count in sorted(out)
    ]


def _modules() -> list[tuple[str, str]]:
    """(text, path from src/) of every module of the package."""
    modules = sorted(PACKAGE.rglob("*.py"))
    assert len(modules) > 10, f"no package at {PACKAGE}"
    return [
        (path.read_text(encoding="utf-8"), path.relative_to(PACKAGE.parents[1]).as_posix())
        for path in modules
    ]


def test_no_module_or_function_too_long() -> None:
    broken = [msg for text, where in _modules() for msg in too_long(text, where)]
    assert not broken, "split these:\n" + "\n".join(broken)


def test_no_function_takes_more_than_6_positional_parameters() -> None:
    broken = [msg for text, where in _modules() for msg in too_many_positional(text, where)]
    assert not broken, "name these parameters:\n" + "\n".join(broken)


def test_the_check_names_what_is_too_long() -> None:
    body = "".join(f"    x{i} = {i}\n" for i in range(MAX_FUNCTION_LINES))
    fits = f"def fits():\n{body[: body.rindex('    x')]}"
    assert too_long(fits, "m.py") == []
    long = f"\n\ndef long_one():\n{body}"
    assert too_long(long, "m.py") == [
        f"m.py:3 long_one, {MAX_FUNCTION_LINES + 1} lines (at most 120)"
    ]
    big = "x = 0\n" * (MAX_MODULE_LINES + 1)
    assert too_long(big, "big.py") == [
        f"big.py: the module, {MAX_MODULE_LINES + 1} lines (at most 600)"
    ]
    assert too_long("x = 0\n" * MAX_MODULE_LINES, "fits.py") == []


def test_the_check_names_what_takes_too_many_positional_parameters() -> None:
    source = """
def six(a, b, c, d, e, f, *, g=0, h=0):
    pass


def seven(a, b, c, d, e, f, g=0):
    pass


def slashed(a, b, /, c, d, e, f, g):
    pass


class Thing:
    def method(self, a, b, c, d, e, f):
        pass

    @classmethod
    def build(cls, a, b, c, d, e, f, g):
        pass


@wp.kernel
def kernel(a: int, b: int, c: int, d: int, e: int, f: int, g: int):
    pass


@warp.func
def helper(a, b, c, d, e, f, g):
    pass


@wp.kernel(enable_backward=False)
def called(a, b, c, d, e, f, g):
    pass


@other.kernel
def not_warp(a, b, c, d, e, f, g, *args, **kwargs):
    pass


class Graph:
    def forward(self, a, b, c, d, e, f, g):
        pass


def forward(a, b, c, d, e, f, g):
    pass
"""
    assert too_many_positional(source, "m.py") == [
        f"m.py:{line} {name}, 7 positional parameters (at most 6; make the rest keyword-only)"
        for line, name in (
            (6, "seven"),
            (10, "slashed"),
            (19, "build"),
            (39, "not_warp"),
            (48, "forward"),
        )
    ]
