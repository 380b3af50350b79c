"""The Python API: load the pretrained set, animate, save, export; simulate ground truth."""

from __future__ import annotations

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

    result.export(tmp_path / "kick.pc2")
    np.testing.assert_array_equal(read_pc2(tmp_path / "kick.pc2")[0], result.vertices)
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


def test_simulate_gives_ground_truth_of_one_motion(skirt):
    from loosefit.sim.cloth import ClothConfig

    result = loosefit.simulate("sway", skirt, frames=3, config=ClothConfig.tiny())
    assert result.source == "newton-vbd" and result.vertices.shape == (3, skirt.num_vertices, 3)
    assert np.isfinite(result.vertices).all()
    with pytest.raises(LoosefitInputError, match="garment"):
        loosefit.simulate("sway", "ballgown", frames=3)


def test_the_runtime_model_imports_neither_the_simulator_nor_the_datasets():
    """``loosefit.model``'s networks and rollouts load without newton, warp, sim/, data/ or
    train/ (only ``model.frames``, the training data's preparation, needs the avatar)."""
    import subprocess
    import sys

    modules = ("rollout", "generative", "motion_encoder", "motion_features", "detail",
               "baselines", "uvmap", "ssdr")  # fmt: skip
    code = ("import sys\n" + "".join(f"import loosefit.model.{m}\n" for m in modules) +
            "bad = [m for m in sys.modules if m.split('.')[0] in ('newton', 'warp') or "
            "m.startswith(('loosefit.sim', 'loosefit.data', 'loosefit.train'))]\n"
            "print(bad)\nsys.exit(1 if bad else 0)\n")  # fmt: skip
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
