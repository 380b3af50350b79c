"""The Python API: load the pretrained set, animate, save, export; simulate ground truth."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import loosefit
from loosefit.errors import LoosefitInputError


@pytest.fixture(scope="module")
def model():
    return loosefit.load()


def test_the_readme_example_animates_saves_and_exports(model, tmp_path):
    result = model.animate("kick", frames=24)
    assert isinstance(result, loosefit.AnimatedGarment)
    assert result.vertices.shape == (24, model.template.num_vertices, 3)
    assert result.fps == model.fps == 30.0 and result.num_frames == 24
    assert result.body_vertices.shape[0] == 24 and result.body_faces.shape[1] == 3
    assert np.isfinite(result.vertices).all()
    # the skirt hangs around the hips: within half a metre of the body's centre
    assert np.abs(result.vertices.mean(1) - result.body_vertices.mean(1)).max() < 0.5
    again = loosefit.AnimatedGarment.load(result.save(tmp_path / "kick.npz"))
    np.testing.assert_array_equal(again.vertices, result.vertices)
    assert again.motion.joint_names == result.motion.joint_names
    from loosefit.export import read_pc2
    from loosefit.export.meshes import in_up_axis

    result.export(tmp_path / "kick.pc2")  # Y up, as the OBJ beside it
    cache = read_pc2(tmp_path / "kick.pc2")[0]
    np.testing.assert_array_equal(cache, in_up_axis(result.vertices, "Y"))
    # longer than the motion: it plays again; a Motion object works as a file does
    longer = model.animate(result.motion, frames=40)
    assert longer.num_frames == 40
    np.testing.assert_allclose(longer.vertices[:24], result.vertices, atol=1e-5)


def test_bad_inputs_are_clear_errors(model, tmp_path):
    with pytest.raises(LoosefitInputError, match="no such file"):
        loosefit.load(tmp_path / "missing.pt")
    with pytest.raises(LoosefitInputError, match="moonwalk"):
        model.animate("moonwalk")
    with pytest.raises(LoosefitInputError, match="at least 1"):
        model.animate("kick", frames=0)
    motion = model.animate("kick", frames=4).motion
    motion.fps = 60.0
    with pytest.raises(LoosefitInputError, match="fps"):
        model.animate(motion)
    with pytest.raises(AttributeError):
        loosefit.not_a_function  # noqa: B018
    with pytest.raises(LoosefitInputError, match="full or realtime"):
        model.animate("kick", frames=4, collision="fast")


def test_threads_are_checked_and_set_for_the_call_alone(model):
    import torch

    seen = []
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        model.animate(
            "kick", frames=3, threads=1, progress=lambda *_: seen.append(torch.get_num_threads())
        )
        assert seen and set(seen) == {1} and torch.get_num_threads() == 2
        for bad in (0, 1.5, "2"):
            with pytest.raises(LoosefitInputError, match="threads.*at least 1"):
                model.animate("kick", frames=3, threads=bad)
        with pytest.raises(LoosefitInputError, match="threads.*at least 1"):
            model.animate_batch(["kick", "spin"], frames=3, threads=-1)
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)


def test_realtime_collision_handling_keeps_the_cloth_out_with_fewer_rounds(model):
    # the same frames, collision handling cut to one solve and one round of its last steps:
    # the model's own configuration is back afterwards
    full = model.animate("kick", frames=45)
    quick = model.animate("kick", frames=45, collision="realtime")
    assert model.model.collision.iterations == 4 and model.model.collision.relax == 8
    assert np.isfinite(quick.vertices).all()
    assert np.abs(quick.vertices - full.vertices).max() > 0  # other rounds ran
    from loosefit.eval.metrics import inside_fraction

    for garment in (full, quick):  # a little cloth within a millimetre of the skin at most
        inside = inside_fraction(garment.vertices, garment.body_vertices, garment.body_faces)
        assert inside.max() < 0.01


def test_cli_animate_collision_realtime(tmp_path, capsys):
    from loosefit.cli import main

    args = ["animate", "kick", "--frames", "6", "--out", str(tmp_path / "k.npz")]
    assert main([*args, "--collision", "realtime"]) == 0
    assert loosefit.AnimatedGarment.load(tmp_path / "k.npz").num_frames == 6
    with pytest.raises(SystemExit):  # argparse: not one of the choices
        main([*args, "--collision", "fast"])
    assert "invalid choice: 'fast'" in capsys.readouterr().err


def test_the_committed_set_keeps_its_edges_and_one_from_before_the_terms_says_so(model, tmp_path):
    import torch

    from loosefit.api import pretrained_checkpoint
    from loosefit.inference.checkpoints import load_torch
    from loosefit.inference.stages import Stages
    from loosefit.inference.stages.lengths import hanging_edges
    from loosefit.model.losses import PHYSICS_TERMS, ClothStructure, signed_edge_change

    # the committed set was trained with every physics term
    assert model.model.missing_physics_terms == ()
    t = model.template
    s = ClothStructure.from_template(t)
    s = s.with_edges(hanging_edges(t.vertices, s.edges, 0.6))

    def median_change(x) -> float:
        return float(signed_edge_change(torch.from_numpy(x), s.edges, s.rest_lengths).median())

    # its skirt keeps its length: the hanging edges within 2 % of rest at the median; without
    # the edge-length stage they are shorter (6.3 %, detail included), but less so than the
    # set before this issue (8.0 % on this motion)
    assert abs(median_change(model.animate("kick", frames=24).vertices)) < 0.02
    without = model.animate("kick", frames=24, stages=Stages(lengths=False))
    assert -0.075 < median_change(without.vertices) < -0.02

    # the same set with its record of the terms taken away, as a checkpoint written before
    # the physics terms: it loads, animates, and says that it lacks them
    for name in ("generative.pt", "motion.pt"):
        data = load_torch(pretrained_checkpoint().parent / name)
        data.pop("physics_terms", None)
        torch.save(data, tmp_path / name)
    old = loosefit.load(tmp_path / "motion.pt")
    assert old.model.missing_physics_terms == PHYSICS_TERMS
    assert np.isfinite(old.animate("kick", frames=4).vertices).all()


def test_simulate_gives_ground_truth_of_one_motion(skirt):
    from loosefit.sim.cloth_config import ClothConfig

    result = loosefit.simulate("sway", skirt, frames=3, config=ClothConfig.tiny())
    assert result.source == "newton-vbd" and result.vertices.shape == (3, skirt.num_vertices, 3)
    assert np.isfinite(result.vertices).all()
    with pytest.raises(LoosefitInputError, match="garment"):
        loosefit.simulate("sway", "ballgown", frames=3)


def _imports_in_fresh_interpreter(modules: list[str]) -> set[str]:
    """The modules that importing ``modules`` loads, in a new interpreter."""
    import json
    import subprocess
    import sys

    code = (
        "import json, sys\n"
        + "".join(f"import {m}\n" for m in modules)
        + "print(json.dumps(sorted(sys.modules)))\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    return set(json.loads(run.stdout.splitlines()[-1]))


def test_the_model_package_imports_neither_the_simulator_nor_the_datasets():
    """Every module of ``loosefit.model`` (the networks), and the rollout, load without newton,
    warp, sim/, data/ or train/."""
    import pkgutil

    import loosefit.model

    modules = [f"loosefit.model.{m.name}" for m in pkgutil.iter_modules(loosefit.model.__path__)]
    assert "loosefit.model.generative" in modules and len(modules) >= 8
    modules += ["loosefit.inference.rollout", "loosefit.inference.timeline"]
    loaded = _imports_in_fresh_interpreter(modules)
    bad = [
        m
        for m in loaded
        if m.split(".")[0] in ("newton", "warp")
        or m.startswith(("loosefit.sim", "loosefit.data", "loosefit.train"))
    ]
    assert not bad


def test_the_runtime_loads_and_animates_without_the_training_code():
    """The API and the inference module (load, animate, package) import nothing of train/."""
    loaded = _imports_in_fresh_interpreter(
        [
            "loosefit.api",
            "loosefit.inference.animator",
            "loosefit.inference.package",
            "loosefit.export",
            "loosefit.eval.rollouts",
        ]
    )
    assert not [m for m in loaded if m.startswith("loosefit.train")]


def test_nothing_outside_training_imports_train():
    """No module outside ``loosefit/train`` imports it, but for the API's training
    functions (inside the functions of ``api/train.py``, which the CLI's ``train`` commands
    call; a static reading of every import statement, however deep in a function)."""
    import ast

    import loosefit

    root = Path(loosefit.__file__).parent
    offenders = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root)
        if rel.parts[0] == "train":
            continue
        tree = ast.parse(path.read_text(), str(path))
        owner = {}  # every node -> the function it is in (None: module level)
        for top in ast.walk(tree):
            if isinstance(top, ast.FunctionDef | ast.AsyncFunctionDef):
                for node in ast.walk(top):
                    owner.setdefault(node, top.name) if node is not top else None
        for node in ast.walk(tree):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
                if isinstance(node, ast.ImportFrom)
                else []
            )
            if not any(n == "loosefit.train" or n.startswith("loosefit.train.") for n in names):
                continue
            fn = owner.get(node)
            if not (rel == Path("api", "train.py") and fn):
                offenders.append(f"{rel}:{node.lineno} (in {fn or 'the module'})")
    assert not offenders
    # the API's training functions do import it (the check sees them)
    api = (root / "api" / "train.py").read_text()
    assert "from loosefit.train.motion import" in api


def test_a_configured_block_gives_the_model_its_own_stages_back(model):
    from loosefit.inference.stages import Stages
    from loosefit.inference.stages.collision import CollisionConfig
    from loosefit.inference.stages.lengths import LengthConfig

    m = model.model
    own = m.restorer(Stages())
    collision, lengths = m.collision, m.lengths
    with m.configured(CollisionConfig(finish=0), LengthConfig(edges="all")):
        assert m.collision.finish == 0 and m.restorer(Stages()) is not own
    assert m.collision is collision and m.lengths is lengths and m.restorer(Stages()) is own


@pytest.mark.parametrize("folder", ["dance", "salsa"])
def test_one_animate_reads_each_checkpoint_file_once(folder, monkeypatch):
    """``loosefit.load(...).animate(...)`` reads every file of the set once: the motion
    stage, the generative stage it records and what lies beside it (the dance set's
    residual process, the salsa set's detail stage)."""
    from collections import Counter

    import torch

    from tests.conftest import REPO

    reads: Counter = Counter()
    real = torch.load

    def counted(f, *args, **kwargs):
        reads[Path(f).name] += 1
        return real(f, *args, **kwargs)

    monkeypatch.setattr(torch, "load", counted)
    loosefit.load(REPO / "checkpoints" / folder / "motion.pt").animate("sway", frames=3)
    beside = {"salsa": {"detail.pt": 1}, "dance": {"residual.pt": 1}}[folder]
    want = {"motion.pt": 1, "generative.pt": 1} | beside
    assert dict(reads) == want


def test_animate_keeps_the_rollout_s_figures_and_takes_its_options_by_name(model):
    result = model.animate("sway", frames=5)
    assert result.rollout is not None
    np.testing.assert_array_equal(result.rollout.vertices, result.vertices)
    assert result.rollout.frames > 5 and len(result.rollout.collisions) == 5  # preroll first
    assert loosefit.AnimatedGarment.rollout is None  # one read from a file has none
    with pytest.raises(TypeError):
        model.animate("sway", 5, 0, 0, None, None, "torch")  # runtime only by name
    assert model.avatar() is model.model.avatar()  # the trained body's


def test_motion_for_caps_a_motion_before_playing_it_again(model):
    from loosefit.api import motion_for

    avatar = model.model.avatar()
    whole = motion_for("sway", avatar, model.fps)
    capped = motion_for("sway", avatar, model.fps, max_frames=7)
    assert capped.num_frames == 7
    np.testing.assert_array_equal(capped.rotations, whole.rotations[:7])
    again = motion_for("sway", avatar, model.fps, 10, max_frames=7)  # 7 frames, played again
    assert again.num_frames == 10
    np.testing.assert_array_equal(again.rotations[:7], capped.rotations)
    given = motion_for(whole, avatar, model.fps, max_frames=4)
    np.testing.assert_array_equal(given.rotations, whole.rotations[:4])


def test_the_pretrained_set_draws_seeded_realisations_of_the_cloth(model):
    from tests.conftest import REPO

    assert model.model.residual is not None  # its residual.pt, beside motion.pt
    centre = model.animate("sway", frames=6).vertices
    one = model.animate("sway", frames=6, realisation=1).vertices
    again = model.animate("sway", frames=6, realisation=1).vertices
    two = model.animate("sway", frames=6, realisation=2).vertices
    np.testing.assert_array_equal(one, again)
    assert 1e-3 < np.abs(one - centre).max() < 0.3  # a take, not another garment
    assert np.abs(one - two).max() > 1e-3
    engine = loosefit.load(REPO / "checkpoints" / "dance" / "engine.pt")
    with pytest.raises(LoosefitInputError, match="realisation"):
        engine.animate("sway", frames=3, realisation=0)
