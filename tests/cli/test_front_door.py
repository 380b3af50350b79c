"""The CLI reaches its work through the public API: every ``src/loosefit/cli/*.py`` imports
of loosefit only ``loosefit``, ``loosefit.api…``, ``loosefit.errors`` and ``loosefit.cli…``
(a static reading with :mod:`ast` of every import statement, however deep in a function),
but for the commands not yet moved onto the API, whose remaining imports are listed here
(each entry must still be true: a command moved onto the API leaves the list)."""

from __future__ import annotations

import ast
from pathlib import Path

CLI = Path(__file__).resolve().parents[2] / "src" / "loosefit" / "cli"

ALLOWED = ("loosefit.api", "loosefit.errors", "loosefit.cli")  # and their modules; and loosefit

# The commands not yet on the API, and the modules they still import (to be moved onto
# public functions of loosefit.api: rendering, data sets, simulation, inspection, viewing).
REMAINING: dict[str, set[str]] = {
    # dressing a character: its sheet of renders
    "character.py": {"loosefit.character", "loosefit.character.sheet"},
    # the shared options: the avatar, BVH units and retargeting, garments, render, threads
    "common.py": {
        "loosefit.body.avatar",
        "loosefit.export",
        "loosefit.fitting.place",
        "loosefit.inference.stages",
        "loosefit.inference.threads",
        "loosefit.motion.bvh",
        "loosefit.motion.retarget",
        "loosefit.render.clip",
        "loosefit.render.renderer",
    },
    # demo --physics / --no-physics (the learned demo goes through loosefit.load)
    "demo.py": {
        "loosefit.export",
        "loosefit.fitting.place",
        "loosefit.sequence",
        "loosefit.sim.cloth_config",
        "loosefit.sim.driver",
    },
    "garment.py": {
        "loosefit.fitting.drape",
        "loosefit.fitting.place",
        "loosefit.garment.obj",
        "loosefit.render.clip",
        "loosefit.render.renderer",
    },
    "generative.py": {
        "loosefit.data.format",
        "loosefit.eval.metrics",
        "loosefit.inference.checkpoints",
        "loosefit.model.motion_features",
        "loosefit.render.clip",
        "loosefit.render.renderer",
        "loosefit.sequence",
    },
    "motion.py": {
        "loosefit.motion.inspect",
        "loosefit.motion.joint_map_files",
        "loosefit.motion.motions",
        "loosefit.motion.pose_check",
        "loosefit.motion.retarget",
        "loosefit.render.skeleton_sheet",
    },
    "render.py": {"loosefit.data.format", "loosefit.fitting.place", "loosefit.motion.motions"},
    "simulate.py": {
        "loosefit.garment.dress",
        "loosefit.garment.importer",
        "loosefit.garment.skirt",
        "loosefit.sim.cluster",
        "loosefit.sim.dataset_config",
        "loosefit.sim.generate",
        "loosefit.sim.presets",
        "loosefit.sim.report",
    },
    # the colourings' names as the parser's choices, read without importing the API
    "view.py": {"loosefit.view.config"},
}


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


def test_every_command_goes_through_the_api_but_the_listed_remains():
    seen = {}
    for path in sorted(CLI.glob("*.py")):
        seen[path.name] = outside_the_front_door(loosefit_imports(path.read_text()))
    extra = {n: sorted(m - REMAINING.get(n, set())) for n, m in seen.items()}
    assert not {n: m for n, m in extra.items() if m}, "import these through loosefit.api"
    stale = {n: sorted(REMAINING[n] - seen.get(n, set())) for n in REMAINING}
    assert not {n: m for n, m in stale.items() if m}, "no longer imported: drop from REMAINING"


def test_animate_and_demo_reach_their_model_through_the_api_alone():
    for name in ("animate.py", "package.py", "train.py"):
        assert not outside_the_front_door(loosefit_imports((CLI / name).read_text())), name
    demo = loosefit_imports((CLI / "demo.py").read_text())
    assert not any(m.startswith(("loosefit.inference", "loosefit.motion")) for m in demo)
