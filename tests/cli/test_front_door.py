"""The CLI reaches its work through the public API: every ``src/loosefit/cli/*.py`` imports
of loosefit only ``loosefit``, ``loosefit.api…``, ``loosefit.errors`` and ``loosefit.cli…``
(a static reading with :mod:`ast` of every import statement, however deep in a function)."""

from __future__ import annotations

import ast
from pathlib import Path

CLI = Path(__file__).resolve().parents[2] / "src" / "loosefit" / "cli"

ALLOWED = ("loosefit.api", "loosefit.errors", "loosefit.cli")  # and their modules; and loosefit


def loosefit_imports(source: str) -> set[str]:
    """The loosefit modules one module's source imports (``from loosefit import x`` counts
    as ``loosefit.x``)."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module == "loosefit":
                found |= {f"loosefit.{a.name}" for a in node.names}
            else:
                found.add(node.module)
        elif isinstance(node, ast.ImportFrom):  # a relative import: inside loosefit.cli
            found.add("loosefit.cli")
    return {m for m in found if m.split(".")[0] == "loosefit"}


def outside_the_front_door(modules: set[str]) -> set[str]:
    """The imports of ``modules`` that are not the API, the errors or the CLI itself."""
    inside = {m for m in modules if any(m == a or m.startswith(a + ".") for a in ALLOWED)}
    return modules - inside - {"loosefit"}


def test_the_reading_sees_every_kind_of_import():
    source = (
        "import loosefit\nimport loosefit.sim.driver\nfrom loosefit import sequence\n"
        "def f():\n    from loosefit.api import load\n    from loosefit.render.clip import x\n"
    )
    found = loosefit_imports(source)
    assert found == {
        "loosefit",
        "loosefit.sim.driver",
        "loosefit.sequence",
        "loosefit.api",
        "loosefit.render.clip",
    }
    assert outside_the_front_door(found) == {
        "loosefit.sim.driver",
        "loosefit.sequence",
        "loosefit.render.clip",
    }
    # a module whose name only begins like an allowed one is outside
    assert outside_the_front_door({"loosefit.apiary", "loosefit.errors"}) == {"loosefit.apiary"}


def test_every_command_goes_through_the_api():
    seen = {}
    for path in sorted(CLI.glob("*.py")):
        seen[path.name] = sorted(outside_the_front_door(loosefit_imports(path.read_text())))
    assert len(seen) > 15 and "simulate.py" in seen  # the commands were read
    assert not {n: m for n, m in seen.items() if m}, "import these through loosefit.api"


def test_animate_and_demo_reach_their_model_through_the_api_alone():
    for name in ("animate.py", "package.py", "train.py"):
        assert not outside_the_front_door(loosefit_imports((CLI / name).read_text())), name
    demo = loosefit_imports((CLI / "demo.py").read_text())
    assert not any(m.startswith(("loosefit.inference", "loosefit.motion")) for m in demo)
