"""The animation pipeline's learned stages in onnxruntime: ``animate(..., runtime="onnx")``.

:func:`~loosefit.inference.rollout.rollout` runs the same timeline either way; with this
runtime its two network calls go through onnxruntime instead of PyTorch (faster
on one core):

* the motion stage's step (:class:`StepGraph`, one frame): the dynamic motion encoder
  (Eq. 9, its GRU state in and out) and the decoders with the UV sampling, garments in
  the frame's root frame::

      features (B, F), previous (B, V, 3), hidden (B, G)
          -> latent (B, Z), next_hidden (B, G), garment (B, V, 3)

* the detail generator (paper 3.4): ``garment (B, V, 3), latent (B, Z) -> offset (B, V, 3)``.

Everything else is the same Python code as with ``runtime="torch"``: the motion features
and root frames (computed for all frames at once), the divergence check, the edge-length
stage, collision handling, feedback, and the later stages' overlap on a second thread
(``Stages.overlap``; the detail graph then runs on that thread in its own session, and
onnxruntime lets go of the GIL while it runs). Each session has as many intra-op threads
as torch has (``torch.get_num_threads()`` when the rollout starts, which ``animate``'s
``threads`` sets: :mod:`loosefit.inference.threads`; one on one thread, so that the
one-thread figures of ``bench/speed/rollout_speed.py`` are one core's).

The garments before collision handling are PyTorch's within float rounding: over 300
frames of the pretrained set, 5e-7 m after the decoders and the detail stage, 3e-6 m after
the edge lengths (the tests ask for 1e-4 m). Collision handling is the same code, but it
is not continuous in its input: a vertex at the edge of its contact set by a micrometre
can be pushed out otherwise, so after it a few vertices of a few frames differ by
millimetres (0.8 mm over those 300 frames, 16 vertex-frames of 705,600; up to 23 mm on
150 frames of bench/speed/rollout_speed.py's clips, 99.9 % within 4e-5 m). PyTorch's own
garments with 1e-6 m of noise added after the detail stage move up to 8 mm after it
(docs/results/BENCHMARKS.md, "The onnx runtime").

Unlike the engine graph of :mod:`loosefit.inference.onnx.export` (motion features and root
frames inside, world garments), these graphs take what the rollout already computes; they
share its UV sampling (:class:`~loosefit.inference.onnx.export.GatherSample`) and decoders.

**Exported in memory, not cached on disk.** :class:`OnnxStages` exports both graphs when
a model first animates with this runtime and keeps them (and a session per thread count)
on the model for the rest of the process. Measured on dev-cpu (2 cores, shared,
2026-11-26, the pretrained set, one thread): the export, the check and the sessions take
0.7 s of CPU (1.0 s wall), against 0.9 s of CPU (1.7 s wall) to load the model, and pay for
themselves within about 120 frames (the motion stage 7.7 -> 4.4 ms of CPU a frame, the
detail stage 3.1 -> 0.9 ms). A disk cache would save under a second per process at the
price of 25 MB per checkpoint under the user's cache folder, a fingerprint of the weights
to hash every time, and files to keep in step with torch and onnxruntime versions. The
graphs are exported again when the model's encoder, generative model or detail module is
replaced by another object, not when weights are changed in place.
"""

from __future__ import annotations

import copy
import io

import numpy as np
import torch
from torch import nn

from loosefit.errors import LoosefitInputError
from loosefit.inference.onnx.export import (
    GatherSample,
    check_exportable,
    decode,
    needs_package,
    trace_graph,
)

SOURCE = "runtime 'onnx'"  # what the errors name
OPSET = 17
TOLERANCE = 1e-4  # m: the first frame's largest allowed difference from PyTorch
DETAIL_BATCH = 8  # frames per detail call: per frame, 8 took 0.93 ms of CPU, 1 and 64 1.1 ms
STEP_INPUTS = ("features", "previous", "hidden")
STEP_OUTPUTS = ("latent", "next_hidden", "garment")
DETAIL_INPUTS = ("garment", "latent")


class StepGraph(nn.Module):
    """One frame of the motion stage for B characters, garments in their root frames.

    Args:
        model: an :class:`~loosefit.inference.animator.AnimationModel`.
    """

    def __init__(self, model) -> None:
        super().__init__()
        self.generative, self.encoder = model.generative, model.encoder
        self.sample = GatherSample(model.generative.uv)

    def forward(
        self, features: torch.Tensor, previous: torch.Tensor, hidden: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Features (B, F), the previous garment (B, V, 3) and the GRU state (B, G) to
        Z_t (B, Z), the next GRU state (B, G) and the decoded garment (B, V, 3)."""
        z, hidden = self.encoder(features, previous, hidden)
        return z, hidden, decode(self.generative, self.sample, z)


def _export(module: nn.Module, example: tuple, inputs, outputs) -> bytes:
    """``module`` (on the CPU, in eval mode) as an ONNX graph in memory, batch size free."""
    buffer = io.BytesIO()
    trace_graph(module, example, buffer, inputs, outputs, OPSET)
    return buffer.getvalue()


def _session(graph: bytes, threads: int):
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads = threads
    options.inter_op_num_threads = 1
    if threads > 1:  # idle workers sleep: the other stage's thread may need the core
        options.add_session_config_entry("session.intra_op.allow_spinning", "0")
    return ort.InferenceSession(graph, options, providers=["CPUExecutionProvider"])


class OnnxStep:
    """The motion stage's network call in an onnxruntime session, as
    :class:`~loosefit.inference.rollout.MotionStage`'s ``step`` takes it: ``step(features (B, F),
    previous (B, V, 3), hidden (B, G)) -> (Z_t (B, Z), hidden (B, G), garment (B, V, 3))``,
    CPU float32 tensors."""

    def __init__(self, session) -> None:
        self.session = session
        # an input the graph does not read (previous, for the "w/o ps" encoder) is not in it
        self.inputs = [i.name for i in session.get_inputs()]

    def __call__(
        self, features: torch.Tensor, previous: torch.Tensor, hidden: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        feed = {"features": features, "previous": previous, "hidden": hidden}
        feed = {k: np.ascontiguousarray(feed[k].numpy(), np.float32) for k in self.inputs}
        z, hidden, garment = self.session.run(None, feed)
        return torch.from_numpy(z), torch.from_numpy(hidden), torch.from_numpy(garment)


class OnnxDetail:
    """The detail generator in an onnxruntime session, called as the module is: garments
    (B, V, 3) in their root frames and codes (B, Z) to offsets (B, V, 3), ``DETAIL_BATCH``
    frames per call."""

    def __init__(self, session) -> None:
        self.session = session

    def __call__(self, vertices: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        x = np.ascontiguousarray(vertices.numpy(), np.float32)  # (B, V, 3)
        c = np.ascontiguousarray(z.numpy(), np.float32)  # (B, Z)
        parts = [
            self.session.run(
                None, {"garment": x[s : s + DETAIL_BATCH], "latent": c[s : s + DETAIL_BATCH]}
            )[0]
            for s in range(0, len(x), DETAIL_BATCH)
        ]
        return torch.from_numpy(np.concatenate(parts) if len(parts) != 1 else parts[0])


class OnnxStages:
    """One model's learned stages as ONNX graphs (exported in memory, checked against
    PyTorch on a frame), with onnxruntime sessions by thread count.

    Args:
        model: an :class:`~loosefit.inference.animator.AnimationModel` on the CPU.

    Raises:
        LoosefitInputError: the ``onnx`` extra missing (``pip install 'loosefit[onnx]'``),
            a model on another device, a stage the graphs do not hold, or a graph whose
            first frame is more than ``TOLERANCE`` from PyTorch's.
    """

    def __init__(self, model) -> None:
        needs_package("onnxruntime", SOURCE)
        needs_package("onnx", SOURCE)  # torch.onnx.export writes through it
        if model.device.type != "cpu":
            raise LoosefitInputError(
                SOURCE,
                "device",
                "a model on the CPU (onnxruntime runs there)",
                str(model.device),
                hint="use runtime='torch' on a GPU",
            )
        check_exportable(model)
        self.source = model.path
        self.encoder, self.generative = model.encoder, model.generative
        step = copy.deepcopy(StepGraph(model)).cpu().eval()  # the model stays put
        rest = model.rest_state.float().cpu()[None].expand(2, -1, -1).contiguous()  # (2, V, 3)
        mean = model.encoder.feature_mean.float().cpu()[None].expand(2, -1).clone()  # (2, F)
        self.example = (mean, rest, torch.zeros(2, model.encoder.config.gru))
        self.step_graph = _export(step, self.example, STEP_INPUTS, STEP_OUTPUTS)
        with torch.no_grad():  # PyTorch's answer on the example: the checks' reference
            self._expected = step(*self.example)  # Z_t (2, Z), hidden (2, G), garment (2, V, 3)
        self.detail_module: nn.Module | None = None  # the one detail_graph was exported from
        self.detail_graph: bytes | None = None
        self._sessions: dict = {}  # ("step" | "detail", threads) -> session
        self._check_step()

    def built_from(self, model) -> bool:
        """Whether these graphs are of ``model``'s encoder and generative model."""
        return self.encoder is model.encoder and self.generative is model.generative

    def runners(self, detail: nn.Module | None, threads: int) -> tuple[OnnxStep, OnnxDetail | None]:
        """The step and (when ``detail`` is given) the detail stage, each in a session with
        ``threads`` intra-op threads (exported and made once)."""
        step = OnnxStep(self._session("step", threads))
        if detail is None:
            return step, None
        if detail is not self.detail_module:
            module = copy.deepcopy(detail).cpu().eval()
            z, _, garment = self._expected  # the example frame's code and garment
            self.detail_graph = _export(module, (garment, z), DETAIL_INPUTS, ("offset",))
            self.detail_module = detail
            self._sessions = {k: v for k, v in self._sessions.items() if k[0] != "detail"}
            self._check_detail(module, garment, z)
        return step, OnnxDetail(self._session("detail", threads))

    def _session(self, kind: str, threads: int):
        key = (kind, threads)
        if key not in self._sessions:
            graph = self.step_graph if kind == "step" else self.detail_graph
            self._sessions[key] = _session(graph, threads)
        return self._sessions[key]

    def _check(self, what: str, got: torch.Tensor, want: torch.Tensor) -> None:
        worst = float((got - want).abs().max())
        if not worst <= TOLERANCE:
            raise LoosefitInputError(
                self.source,
                f"onnx graph: {what}",
                f"onnxruntime within {TOLERANCE} m of PyTorch on a frame",
                f"{worst:.3g} m",
            )

    def _check_step(self) -> None:
        got = OnnxStep(self._session("step", 1))(*self.example)
        self._check("motion stage", got[2], self._expected[2])

    def _check_detail(self, module: nn.Module, garment: torch.Tensor, z: torch.Tensor) -> None:
        with torch.no_grad():
            want = module(garment, z)
        self._check("detail", OnnxDetail(self._session("detail", 1))(garment, z), want)
