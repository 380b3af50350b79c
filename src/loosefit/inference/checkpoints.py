"""Checkpoint files: what every stage's checkpoint holds, and the generative stage's loader.

A checkpoint is a ``torch.save``'d dict with

* ``format``: ``loosefit.generative/1``, ``loosefit.motion/1``, ``loosefit.detail/1``,
  ``loosefit.baseline/1`` or ``loosefit.engine/1`` (:data:`FORMATS`;
  :data:`loosefit.inference.loader.CHECKPOINTS` says what each is, which files hold it
  and what opens it);
* ``model_config``: the configuration of the networks (and, for the animating stages, of
  the rollout) that the weights fit: all the runtime reads to rebuild the model;
* ``model``: the weights (half precision in a packaged set);
* what ties the stages together: the garment (``garment``: its template and
  fingerprint), the previous stage's fingerprint and path, the body, the frame rate.

A training run's checkpoints also hold ``config``, the training configuration (to resume
and for the record), and the optimiser and RNG states; a packaged set has neither. A
checkpoint written before ``model_config`` existed is read from the model part of its
training configuration (:func:`model_config`).

:func:`loosefit.inference.loader.load_model` opens any of them (or a set's folder) as a model
that animates, each file read once.
"""

from __future__ import annotations

import hashlib
import json
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import torch

from loosefit.atomic import atomic_path
from loosefit.errors import LoosefitInputError
from loosefit.garment.fingerprint import garment_fingerprint, same_garment
from loosefit.model.generative import GarmentGenerativeModel, GenerativeConfig
from loosefit.types import GarmentTemplate, _plain

GENERATIVE_FORMAT = "loosefit.generative/1"
MOTION_FORMAT = "loosefit.motion/1"
DETAIL_FORMAT = "loosefit.detail/1"
BASELINE_FORMAT = "loosefit.baseline/1"
ENGINE_FORMAT = "loosefit.engine/1"
RESIDUAL_FORMAT = "loosefit.residual/1"
FORMATS = (
    GENERATIVE_FORMAT,
    MOTION_FORMAT,
    DETAIL_FORMAT,
    BASELINE_FORMAT,
    ENGINE_FORMAT,
    RESIDUAL_FORMAT,
)

# what a wrong stage's checkpoint is, said when one is passed for another
_WHAT = {
    GENERATIVE_FORMAT: "the generative stage",
    MOTION_FORMAT: "the motion stage",
    DETAIL_FORMAT: "the detail stage",
    BASELINE_FORMAT: "a baseline",
    ENGINE_FORMAT: "the engine tier",
    RESIDUAL_FORMAT: "a motion stage's residual process",
}


def _numpy_globals() -> list:
    """What a numpy array in a checkpoint unpickles through (arrays of plain numbers only:
    an object array needs more and is refused)."""
    core = getattr(np, "_core", None) or np.core  # numpy 2 / numpy 1
    dtypes = [
        getattr(np.dtypes, n) for n in dir(np.dtypes) if n.endswith("DType") and n != "ObjectDType"
    ]
    return [core.multiarray._reconstruct, np.ndarray, np.dtype, *dtypes]


def load_torch(path: str | Path, device="cpu"):
    """``torch.load`` of a file that runs no code: weights-only unpickling (tensors, numbers,
    strings, containers, and arrays of numbers); anything else in the file is refused.

    Raises:
        LoosefitInputError: unreadable, or holding anything else (a pickled object).
    """
    path = Path(path)
    try:
        with torch.serialization.safe_globals(_numpy_globals()):
            return torch.load(path, map_location=device, weights_only=True)
    except Exception as exc:  # noqa: BLE001 - any unreadable file is the same error for the user
        text = str(exc).strip().splitlines()
        unsafe = next((t for t in text if "Unsupported global" in t or "GLOBAL" in t), None)
        found = (
            f"a file that would run code to load ({unsafe.strip()})"
            if unsafe
            else (text[0] if text else type(exc).__name__)
        )
        raise LoosefitInputError(
            path,
            "<file>",
            "a torch checkpoint of tensors and plain data (loaded weights-only: no code runs)",
            found,
        ) from exc


def save_atomic(data: dict, path: Path) -> None:
    """``torch.save`` to a temporary file, then a rename: never a half-written checkpoint.
    A checkpoint (a dict with a loosefit ``format``) records the version that wrote it."""
    from loosefit import __version__

    if str(data.get("format", "")).startswith("loosefit."):
        data = {**data, "loosefit_version": __version__}
    with atomic_path(Path(path)) as tmp:
        torch.save(data, tmp)


def read_checkpoint_file(
    path: str | Path,
    fmt: str,
    device="cpu",
    hints: dict | None = None,
    *,
    data: dict | None = None,
):
    """A checkpoint's dict, checked to carry ``format == fmt``.

    Args:
        path: the file.
        fmt: the expected format string.
        device: ``map_location``.
        hints: a hint to show per format found instead (by default: which stage it is).
        data: the file's contents when already read (each file is read once): only checked.

    Raises:
        LoosefitInputError: a missing or unreadable file, or another format.
    """
    return check_format(path, read_file(path, device) if data is None else data, fmt, hints)


def read_file(path: str | Path, device="cpu"):
    """A checkpoint file's contents (:func:`load_torch`), a clear error when it is missing.

    Raises:
        LoosefitInputError: a missing or unreadable file.
    """
    path = Path(path)
    if not path.is_file():
        raise LoosefitInputError(path, "<file>", "a checkpoint file", "no such file")
    return load_torch(path, device)


def check_format(path: str | Path, data, fmt: str, hints: dict | None = None):
    """``data``, a checkpoint read from ``path``, checked to carry ``format == fmt``
    (:func:`read_checkpoint_file` of a file already read).

    Raises:
        LoosefitInputError: another format, or another version of this one.
    """
    path = Path(path)
    found = data.get("format") if isinstance(data, dict) else None
    kind, _, version = fmt.rpartition("/")
    if isinstance(found, str) and found.startswith(kind + "/") and found != fmt:
        theirs = found.rpartition("/")[2]
        newer = theirs.isdigit() and version.isdigit() and int(theirs) > int(version)
        from loosefit import __version__

        raise LoosefitInputError(
            path,
            "format",
            f"{fmt!r} (what loosefit {__version__} reads)",
            f"{found!r}, written by loosefit {data.get('loosefit_version', 'of another version')}",
            hint="upgrade loosefit to read it"
            if newer
            else "retrain or repackage it with this version",
        )
    if found != fmt:
        found = found if isinstance(found, str) else None if found is None else repr(found)
        hint = (hints or {}).get(found)
        if hint is None and found in _WHAT:
            hint = f"this is {_WHAT[found]}'s checkpoint; pass {_WHAT[fmt]}'s"
        raise LoosefitInputError(path, "format", repr(fmt), repr(found), hint=hint)
    return data


@contextmanager
def checkpoint_fields(path: str | Path, what: str):
    """Turn a malformed checkpoint's failures (a field missing, or of another type or shape)
    into the :class:`~loosefit.errors.LoosefitInputError` of the file and the field."""
    try:
        yield
    except LoosefitInputError:
        raise
    except KeyError as exc:
        raise LoosefitInputError(
            path,
            str(exc.args[0]) if exc.args else "<field>",
            "present",
            "missing",
            hint=f"not a whole {what}",
        ) from exc
    except (TypeError, ValueError, IndexError, AttributeError, RuntimeError) as exc:
        detail = str(exc).splitlines()[0] if str(exc) else ""
        raise LoosefitInputError(
            path, "<fields>", f"a {what}", f"{type(exc).__name__}: {detail}"
        ) from exc


def checkpoint_format(path: str | Path) -> str | None:
    """The ``format`` a checkpoint file records (None: not a readable checkpoint)."""
    path = Path(path)
    if not path.is_file():
        return None
    try:
        data = load_torch(path)
    except LoosefitInputError:  # the loaders give the clear error
        return None
    return data.get("format") if isinstance(data, dict) else None


def model_config(data: dict) -> dict:
    """The ``model_config`` of a checkpoint's dict (plain dicts, per format):

    * generative: the :class:`~loosefit.model.generative.GenerativeConfig`;
    * motion: ``{"encoder": MotionEncoderConfig, "rollout": RolloutConfig}``;
    * detail: the :class:`~loosefit.model.detail.DetailConfig`;
    * baseline: ``{"network": BaselineConfig, "rollout": RolloutConfig}``.

    A checkpoint written before the field existed gives the same from its training
    configuration's ``model`` (and ``rollout``) entries.
    """
    if "model_config" in data:
        return data["model_config"]
    config, fmt = data.get("config") or {}, data.get("format")
    if fmt in (MOTION_FORMAT, BASELINE_FORMAT):
        key = "encoder" if fmt == MOTION_FORMAT else "network"
        return {key: config.get("model", {}), "rollout": config.get("rollout", {})}
    return config.get("model", {})


def template_dict(t: GarmentTemplate) -> dict:
    """A garment template as plain arrays (its ``meta`` as JSON), for a checkpoint."""
    out = {
        "vertices": t.vertices,
        "faces": t.faces,
        "uvs": t.uvs,
        "face_uvs": t.face_uvs,
        "waist": t.waist,
        "name": t.name,
        "meta": json.dumps(t.meta or {}, default=_plain),
    }
    if t.rest_vertices is not None:
        out["rest_vertices"] = t.rest_vertices
    return out


def template_from_dict(g: dict) -> GarmentTemplate:
    """The inverse of :func:`template_dict` (a checkpoint from before ``meta`` or
    ``rest_vertices``: none)."""
    return GarmentTemplate(
        g["vertices"],
        g["faces"],
        g["uvs"],
        g["face_uvs"],
        g["waist"],
        g["name"],
        meta=json.loads(g.get("meta") or "{}"),
        rest_vertices=g.get("rest_vertices"),
    )


def garment_record(t: GarmentTemplate) -> dict:
    """A checkpoint's ``garment`` entry: the template and its fingerprint."""
    return {"fingerprint": garment_fingerprint(t.vertices, t.faces), "template": template_dict(t)}


def recorded_checkpoint(
    path: Path,
    recorded: dict,
    given: str | Path | None,
    field: str,
    what: str,
    hint: str | None = None,
) -> Path:
    """The checkpoint a checkpoint was trained on: ``given``, or the one it records
    (``recorded["relative"]`` to ``path``'s folder first, then ``recorded["absolute"]``).

    Raises:
        LoosefitInputError: naming ``path``, ``field`` and every candidate, when none exists.
    """
    if given is not None:
        candidates = [Path(given)]
    else:
        candidates = [path.parent / recorded["relative"]]
        candidates += [Path(recorded["absolute"])] if recorded.get("absolute") else []
    found = next((c for c in candidates if c.is_file()), None)
    if found is None:
        found_text = f"none of {[str(c) for c in candidates]} exists"
        raise LoosefitInputError(path, field, what, found_text, hint=hint)
    return found


def model_fingerprint(model: torch.nn.Module) -> str:
    """A short hash of a model's weights, rounded to half precision (as shared checkpoints are)."""
    h = hashlib.sha256()
    for k, v in sorted(model.state_dict().items()):
        h.update(k.encode())
        h.update(
            v.detach().cpu().half().numpy().tobytes()
            if v.is_floating_point()
            else v.detach().cpu().numpy().tobytes()
        )
    return h.hexdigest()[:16]


def half_weights(weights: dict) -> dict:
    """Floating weights in half precision (a packaged set's)."""
    return {k: (v.half() if v.is_floating_point() else v) for k, v in weights.items()}


def float_weights(weights: dict) -> dict:
    """Floating weights back in single precision."""
    return {k: (v.float() if v.is_floating_point() else v) for k, v in weights.items()}


def load_weights(module: torch.nn.Module, weights: dict, path: Path, what: str) -> None:
    """``module.load_state_dict(weights)`` (as floats), a clear error when they do not fit.

    Raises:
        LoosefitInputError: naming ``path`` and the first mismatch.
    """
    try:
        module.load_state_dict(float_weights(weights))
    except RuntimeError as exc:
        raise LoosefitInputError(
            path, "model", f"weights of {what}", str(exc).splitlines()[0]
        ) from exc


# -- the generative stage (paper 3.2) ---------------------------------------------------------


def read_generative(path: str | Path, template: GarmentTemplate | None = None, device="cpu"):
    """A generative checkpoint's dict and the garment it holds, checked to be of
    ``template``'s garment when given.

    Raises:
        LoosefitInputError: not a generative checkpoint, or another garment.
    """
    path = Path(path)
    data = read_checkpoint_file(path, GENERATIVE_FORMAT, device)
    with checkpoint_fields(path, "generative checkpoint"):
        stored = template_from_dict(data["garment"]["template"])
    if template is not None and not same_garment(template, stored):
        want = garment_fingerprint(template.vertices, template.faces)
        raise LoosefitInputError(
            path,
            "garment",
            f"the garment '{template.name}' ({template.num_vertices} vertices, fingerprint {want})",
            f"'{stored.name}' ({stored.num_vertices} vertices, fingerprint "
            f"{data['garment']['fingerprint']})",
            hint="train a model on this garment's dataset",
        )
    return data, stored


def load_generative(
    path: str | Path, template: GarmentTemplate | None = None, device="cpu"
) -> tuple[GarmentGenerativeModel, dict]:
    """A trained generative model (eval mode) and its checkpoint's dict.

    Raises:
        LoosefitInputError: not a generative checkpoint, another garment than
            ``template``'s, or weights that do not fit the configuration it records.
    """
    path = Path(path)
    data, stored = read_generative(path, template, device)
    with checkpoint_fields(path, "generative checkpoint"):
        config = GenerativeConfig(**model_config(data))
        ssdr = None
        if config.decoder == "ssdr":
            m = data["model"]
            B = m["ssdr_weights"].shape[1]
            ssdr = (
                m["ssdr_rest"].float().cpu(),
                m["ssdr_weights"].float().cpu(),
                torch.zeros(B, 3, 4),
            )
        basis = None
        if config.decoder == "basis":  # the basis's buffers, the state dict's below
            m = data["model"]
            basis = tuple(m[k].float().cpu() for k in ("basis_mean", "basis_dirs", "basis_scale"))
        model = GarmentGenerativeModel(stored, config, ssdr=ssdr, basis=basis).to(device)
        load_weights(model, data["model"], path, "this generative configuration")
    return model.eval(), data


def stage_fingerprints(model) -> dict:
    """What the stages beside a motion stage (a detail stage, a residual process) are tied
    to: the motion stage's weights and the garment (``model``: an ``AnimationModel``)."""
    t = model.template
    return {
        "motion": model_fingerprint(model.encoder),
        "garment": garment_fingerprint(t.vertices, t.faces),
    }


def check_fingerprints(model, path: Path, data: dict, kind: str) -> None:
    """A file's recorded stages against ``model``'s (:func:`stage_fingerprints`).

    Raises:
        LoosefitInputError: another garment or motion stage, naming both fingerprints and
            ``kind``, what the file holds ("a detail stage trained on").
    """
    have = stage_fingerprints(model)
    for key, what in (("garment", "garment"), ("motion", "motion stage")):
        if data["fingerprints"][key] != have[key]:
            raise LoosefitInputError(
                path,
                f"fingerprints.{key}",
                f"the {what} of {Path(model.path).name} (fingerprint {have[key]})",
                f"{kind} another {what} (fingerprint {data['fingerprints'][key]})",
            )
