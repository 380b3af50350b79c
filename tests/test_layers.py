"""The package's layers: every import points down.

The units are ``src/loosefit``'s top-level modules and subpackages, and the few modules of a
package that sit in a higher layer than the rest of it (``fitting.drape`` drapes with the
runtime's collision handling, while the simulator places garments with ``fitting.place``);
:data:`LAYERS` orders them bottom to top. A unit imports only units of lower layers (and
itself): never one of its own layer, never one above. Every ``import`` statement counts,
however deep in a function (a static reading of the source with :mod:`ast`, relative
imports resolved), so a convenience that reaches up (``AnimatedGarment.view``) lives in
the upper layer.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "loosefit"

LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors",),  # LoosefitInputError
    ("types", "atomic", "progress", "warp_log"),  # Motion, GarmentTemplate; atomic writes;
    # progress bars; warp imported with its messages on standard error
    ("geometry",),  # pure mesh geometry: edges, normals, skinning, queries, signed distances
    ("body",),  # the avatar, its capsules and regions
    ("motion",),  # motion files read, retargeted, checked, corrected; procedural motions
    ("garment",),  # parametric garments, garment files, mesh checks, quality figures
    ("fitting", "export", "model"),  # garments made for and placed on the body; exporters;
    # the networks and their losses
    ("sequence",),  # GarmentSequence, in memory and on disk
    ("data",),  # the data set format and readers
    ("sim", "render"),  # the simulator and data sets of it; the renderer
    ("inference",),  # the runtime: checkpoints, the rollout and its stages, ONNX
    ("eval", "fitting.drape", "character"),  # metrics and a model's rollouts scored; a
    # garment fitted by draping it; a user's own character fitted and dressed
    ("view",),  # the viewer (colours by the metrics)
    ("train",),  # the training stages
    ("api",),  # the Python API
    ("cli",),  # the `loosefit` commands
    ("__init__", "__main__"),  # the package itself: the API imported on first use
)


def _layer_of() -> dict[str, int]:
    return {unit: i for i, layer in enumerate(LAYERS) for unit in layer}


def _unit(rel: Path) -> str:
    dotted = ".".join(rel.with_suffix("").parts)
    for unit in _layer_of():
        if "." in unit and (dotted == unit or dotted.startswith(unit + ".")):
            return unit
    return rel.parts[0].removesuffix(".py")


def _imported_units(rel: Path, tree: ast.AST, units: set[str]) -> list[tuple[int, str, str]]:
    """(line, unit, statement) for every import of a loosefit unit in one module."""
    package = ["loosefit", *rel.parts[:-1]]  # the module's package, for relative imports
    found = []
    for node in ast.walk(tree):
        targets: list[list[str]] = []
        if isinstance(node, ast.Import):
            targets = [alias.name.split(".") for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - (node.level - 1)] if node.level else []
            module = base + (node.module.split(".") if node.module else [])
            if module == ["loosefit"]:  # from loosefit import sequence
                targets = [["loosefit", alias.name] for alias in node.names]
            else:
                targets = [module]
        for parts in targets:
            if len(parts) >= 2 and parts[0] == "loosefit":
                sub = ".".join(parts[1:3])
                unit = sub if sub in units else parts[1]
                if unit in units:
                    found.append((node.lineno, unit, ast.unparse(node)))
    return sorted(found)


def _modules() -> list[Path]:
    return sorted(p.relative_to(PACKAGE) for p in PACKAGE.rglob("*.py"))


def test_every_unit_has_a_layer():
    """A new top-level module or subpackage is placed in :data:`LAYERS` when it is made."""
    declared = _layer_of()
    missing = sorted({_unit(rel) for rel in _modules()} - set(declared))
    assert not missing, f"units in no layer (add them to LAYERS): {missing}"


def test_every_import_points_down():
    layer = _layer_of()
    units = set(layer)
    bad = []
    for rel in _modules():
        unit = _unit(rel)
        tree = ast.parse((PACKAGE / rel).read_text(), filename=str(rel))
        for line, target, statement in _imported_units(rel, tree, units):
            if target == unit or layer[target] < layer[unit]:
                continue
            way = "within its layer" if layer[target] == layer[unit] else "up"
            bad.append(
                f"src/loosefit/{rel.as_posix()}:{line}: {unit} (layer {layer[unit]}) -> "
                f"{target} (layer {layer[target]}), {way}: {statement}"
            )
    assert not bad, "imports that do not point down:\n" + "\n".join(bad)


def test_the_reading_resolves_relative_and_package_imports():
    """The reader sees ``from . import``, ``from ..x import`` and ``from loosefit import x``."""
    source = (
        "from loosefit import sequence\n"
        "def f():\n"
        "    from ..view import scene\n"
        "    from . import rollouts\n"
        "    import loosefit.body.avatar\n"
    )
    rel = Path("eval/metrics.py")
    found = _imported_units(rel, ast.parse(source), set(_layer_of()))
    assert [(line, unit) for line, unit, _ in found] == [
        (1, "sequence"),
        (3, "view"),
        (4, "eval"),
        (5, "body"),
    ]


# units a layer above may import but does not: training reads data sets, never simulates
APART: tuple[tuple[str, str, str], ...] = (
    ("train", "sim", "the motion stage reads its rest drape from the data set"),
)


def test_training_runs_no_simulator():
    units = set(_layer_of())
    bad = []
    for unit, other, why in APART:
        for rel in _modules():
            if _unit(rel) != unit:
                continue
            tree = ast.parse((PACKAGE / rel).read_text(), filename=str(rel))
            for line, target, statement in _imported_units(rel, tree, units):
                if target == other:
                    bad.append(f"src/loosefit/{rel.as_posix()}:{line}: {statement} ({why})")
    assert not bad, "imports kept apart:\n" + "\n".join(bad)
