"""The engine tier: its training, its ONNX export and the reference loop (onnxruntime, numpy)."""

import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from loosefit.errors import LoosefitInputError

pytest.importorskip("onnxruntime")


@pytest.fixture(scope="module")
def engine_run(toy_dataset, tmp_path_factory):
    """A small tier trained for two epochs on the toy data set."""
    from loosefit.data.format import DatasetReader
    from loosefit.inference.engine.model import load_engine
    from loosefit.model.engine import EngineConfig
    from loosefit.train.engine import EngineTrainer, TrainEngineConfig
    from loosefit.train.loop import Run, train

    reader = DatasetReader(toy_dataset)
    full = SimpleNamespace(
        rest_state=torch.from_numpy(reader.read("a").garment_vertices[0]) * 0, path="toy-motion.pt"
    )
    full.rest_state = full.rest_state + torch.from_numpy(reader.template.vertices)
    out = tmp_path_factory.mktemp("engine")
    cfg = TrainEngineConfig(
        epochs=2,
        window=8,
        eval_every=1,
        membrane=10.0,
        model=EngineConfig(basis=6, motion_fc=16, gru=12, head=16),
    )
    run = Run.open(out, {"toy": 1}, 0, log=lambda *_: None, progress=False)
    report = train(EngineTrainer(reader, full, cfg, run), run, str(toy_dataset))
    return load_engine(out / "engine.pt"), report, out


def test_training_reports_held_out_errors(engine_run):
    model, report, out = engine_run
    assert set(report["test"]["clips"]) == {"c"}
    assert np.isfinite(report["test"]["rmse_cm"])
    assert (out / "report.md").is_file() and model.tier.config.basis == 6
    assert report["epochs"] == 2 and report["final_loss"]["epoch"] == 2


def test_export_equals_pytorch_over_300_frames(engine_run, tmp_path):
    from loosefit.inference.engine.export import EngineExportConfig, export_engine

    model, _, _ = engine_run
    paths = export_engine(model, tmp_path / "e.onnx", EngineExportConfig(check_frames=300))
    import json

    meta = json.loads(paths[1].read_text())
    assert meta["check"]["frames"] == 300 and meta["check"]["max_difference_m"] <= 1e-5
    assert meta["capsules_in_graph"] and len(meta["capsules"]) == 9
    assert meta["waist_held_by"] == ["pelvis", "abdomen", "waist"] and meta["waist_blend"] == 0.08
    assert meta["joint_names"] == list(model.joint_names)


def test_batch_steps_as_each_alone(engine_run, tmp_path):
    from loosefit.inference.engine.export import EngineExportConfig, export_engine
    from loosefit.inference.engine.runtime import EngineRuntime
    from loosefit.inference.timeline import rollout_timeline
    from loosefit.motion.motions import load_motion

    model, _, _ = engine_run
    export_engine(model, tmp_path / "e.onnx", EngineExportConfig(check_frames=0))
    rt = EngineRuntime(tmp_path / "e.onnx")
    rots, roots = [], []
    for seed in (1, 2, 3):
        m = load_motion("dance:12", model.avatar(), seed=seed, max_frames=20)
        r, p, _ = rollout_timeline(m, model.floor_height, 5, 0.5)
        rots.append(r.astype(np.float32))
        roots.append(p.astype(np.float32))
    rot, root = np.stack(rots, 1), np.stack(roots, 1)  # (T, 3, J, 3, 3), (T, 3, 3)
    together, alone = rt.initial_state(3), [rt.initial_state(1) for _ in range(3)]
    for t in range(len(rot)):
        g, together = rt.step(rot[t], root[t], together, start=t == 0)
        for i in range(3):
            gi, alone[i] = rt.step(rot[t, i : i + 1], root[t, i : i + 1], alone[i], start=t == 0)
            np.testing.assert_allclose(g[i], gi[0], atol=1e-5)


def test_runtime_refuses_another_skeleton(engine_run, tmp_path):
    from loosefit.inference.engine.export import EngineExportConfig, export_engine
    from loosefit.inference.engine.runtime import EngineRuntime

    model, _, _ = engine_run
    export_engine(model, tmp_path / "e.onnx", EngineExportConfig(check_frames=0))
    rt = EngineRuntime(tmp_path / "e.onnx")
    names = list(model.joint_names)
    rt.check_skeleton(names)
    swapped = names[:3] + [names[4], names[3]] + names[5:]
    with pytest.raises(LoosefitInputError, match=rf"joint_names\[3\].*'{names[3]}'.*'{names[4]}'"):
        rt.check_skeleton(swapped)
    with pytest.raises(LoosefitInputError, match=r"joint_names\[30\]"):
        rt.check_skeleton(names[:-1])


def test_the_reference_loop_imports_no_torch():
    code = "import sys, loosefit.inference.engine.runtime; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_export_of_a_model_without_an_engine_tier_says_how(tmp_path):
    from loosefit.api.export import engine_checkpoint

    motion = tmp_path / "motion.pt"
    motion.write_bytes(b"")
    with pytest.raises(LoosefitInputError, match="loosefit train engine"):
        engine_checkpoint(motion)


def test_waist_hold_leaves_the_band_and_pushes_below(skirt):
    from loosefit.inference.engine.export import waist_hold

    w = waist_hold(skirt.vertices, skirt.waist, 0.08)
    z = skirt.vertices[:, 2]
    below = z[skirt.waist].mean() - z
    assert np.all(w[skirt.waist] == 0) and np.all(w[below >= 0.08] == 1)
    middle = (below > 0) & (below < 0.08)
    np.testing.assert_allclose(w[middle], below[middle] / 0.08, rtol=1e-5)
    assert np.all(waist_hold(skirt.vertices, skirt.waist, 0.0) == 1)
    with pytest.raises(LoosefitInputError, match="waist_blend"):
        waist_hold(skirt.vertices, skirt.waist, -1.0)
