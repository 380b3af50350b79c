"""The garment generative model with deformation decomposition (paper 3.2).

A conv VAE on the UV map of the garment's vertex positions::

    S_t = uv.encode(V_t)                      (B, 3, H, W) position map
    mu, logvar = E_gen(S_t)                   4 stride-2 convs (IN, leaky ReLU) + FC, 128-D
    z_s, z_d = FC_s(Z_t), FC_d(Z_t)           two 64-D halves
    T~_t = T + D_rec(z_s)                     unposed garment (V, 3), 4 FC layers   (Eq. 3)
    I_t = uv.sample(D_dyn(z_d))               per-vertex offset from a UV offset map (Eq. 5)
    V_t = T~_t + I_t                          the posed garment                      (Eq. 2)

Garments live in the body's root frame (see :mod:`loosefit.model.motion_features`), so
the latent space holds the deformation, not where the dancer stands or faces.
``D_rec`` predicts the displacement of the unposed garment from the template
``T`` rather than absolute positions (the same function, easier to start).

The ablations of paper 4.2 are configurations of the same class:

* ``decoder="vertex"``: one decoder symmetric to the encoder, whose position
  map read back at the vertices is the garment (no decomposition);
* ``decoder="ssdr"``: a linear decoder from the latent code to the bone
  transforms of a precomputed skinning decomposition (SSDR, Le and Deng 2012),
  whose linear blend skinning is the garment.

And one beyond the paper, for held-out motion:

* ``decoder="basis"``: the garment's deformation decomposed over a linear basis (the
  training garments' principal directions, :func:`~loosefit.model.engine.fit_basis`) and a
  UV offset map for what the basis misses::

      mu = E_gen(S_t) + (P (V_t - M)) / s        the first K entries: the basis's coefficients
      V_t = M + (s z_K) P + uv.sample(D_dyn(z))   z_K: the code's first K entries

  ``M`` the mean garment, ``P`` (K, 3V) the directions, ``s`` (K,) their coefficients'
  standard deviations. It starts as the projection onto the basis (``E_gen``'s output layer
  and ``D_dyn``'s last convolution at zero): a held-out garment is decoded to within what
  the basis can hold (docs/results/DECODER_FLOOR.md), where a learned decoder alone
  generalises only as far as its training frames reach. It has no unposed decoder, so the
  inverse-skinning and template terms do not apply.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
import torch
from torch import nn

from loosefit.errors import LoosefitInputError
from loosefit.model.engine import project, reconstruct
from loosefit.model.uvmap import UVMap
from loosefit.types import GarmentTemplate

DECODERS = ("decomposed", "vertex", "ssdr", "basis")
BASIS_START_LOGVAR = -6.0  # decoder "basis": the posterior's log variance at the start


@dataclass
class GenerativeConfig:
    """Sizes of the generative model (the paper's, where it gives them)."""

    decoder: str = "decomposed"  # the paper's; "vertex", "ssdr" (ablations) or "basis"
    uv_size: int = 64  # H = W of the UV maps; four stride-2 convolutions divide it by 16
    channels: tuple[int, ...] = (32, 64, 128, 256)  # the encoder's four convolutions
    latent: int = 128  # Z_t
    half: int = 64  # z_s and z_d
    rec_hidden: tuple[int, ...] = (256, 512, 1024)  # D_rec: these and the output, 4 FC layers
    ssdr_bones: int = 32  # decoder="ssdr": bones of the skinning decomposition
    basis_size: int = 128  # decoder="basis": K, the basis's directions (at most ``latent``)

    def __post_init__(self) -> None:
        src = "GenerativeConfig"
        if self.decoder not in DECODERS:
            raise LoosefitInputError(src, "decoder", f"one of {DECODERS}", repr(self.decoder))
        if self.uv_size % 16 or self.uv_size < 16:
            raise LoosefitInputError(src, "uv_size", "a multiple of 16", repr(self.uv_size))
        if self.decoder == "basis" and not 0 < self.basis_size <= self.latent:
            raise LoosefitInputError(
                src, "basis_size", f"1..{self.latent} (the latent's size)", self.basis_size
            )
        if len(self.channels) != 4:
            raise LoosefitInputError(src, "channels", "4 widths", repr(self.channels))
        self.channels = tuple(int(c) for c in self.channels)
        self.rec_hidden = tuple(int(c) for c in self.rec_hidden)


def _conv_block(cin: int, cout: int) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(cin, cout, 4, stride=2, padding=1),
        nn.InstanceNorm2d(cout, affine=True),
        nn.LeakyReLU(0.2),
    )


def _up_block(cin: int, cout: int, last: bool) -> nn.Sequential:
    layers: list[nn.Module] = [nn.Upsample(scale_factor=2, mode="bilinear", align_corners=False)]
    layers.append(nn.Conv2d(cin, cout, 3, padding=1))
    if not last:
        layers += [nn.InstanceNorm2d(cout, affine=True), nn.LeakyReLU(0.2)]
    return nn.Sequential(*layers)


class UVEncoder(nn.Module):
    """E_gen: a (B, C, H, W) map to (B, out) features: four stride-2 convs then a FC layer."""

    def __init__(self, in_channels: int, channels: tuple[int, ...], size: int, out: int) -> None:
        super().__init__()
        widths = (in_channels, *channels)
        self.convs = nn.Sequential(*[_conv_block(a, b) for a, b in pairwise(widths)])
        self.fc = nn.Linear(channels[-1] * (size // 16) ** 2, out)

    def forward(self, maps: torch.Tensor) -> torch.Tensor:
        return self.fc(self.convs(maps).flatten(1))


class UVDecoder(nn.Module):
    """A code (B, z) to a (B, out, H, W) map: a FC layer then four upsampling convs."""

    def __init__(self, z: int, channels: tuple[int, ...], size: int, out: int) -> None:
        super().__init__()
        self.start = size // 16
        self.width = channels[-1]
        self.fc = nn.Linear(z, self.width * self.start**2)
        widths = (*channels[::-1], out)
        n = len(widths) - 1
        self.ups = nn.Sequential(
            *[_up_block(a, b, i == n - 1) for i, (a, b) in enumerate(pairwise(widths))]
        )

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        x = nn.functional.leaky_relu(self.fc(z), 0.2)
        return self.ups(x.view(-1, self.width, self.start, self.start))


def _mlp(sizes: tuple[int, ...]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(pairwise(sizes)):
        layers.append(nn.Linear(a, b))
        if i < len(sizes) - 2:
            layers.append(nn.LeakyReLU(0.2))
    return nn.Sequential(*layers)


@dataclass
class GenerativeOutput:
    """What the model gives for a batch of B garments of V vertices.

    Attributes:
        vertices: (B, V, 3) the posed garment V_t, root frame.
        unposed: (B, V, 3) T~_t, canonical frame (decoder "decomposed"; else None).
        offsets: (B, V, 3) I_t (decoder "decomposed"; else None).
        mu, logvar: (B, latent) the Gaussian posterior.
        z: (B, latent) the code decoded (a sample in training, mu otherwise).
    """

    vertices: torch.Tensor
    mu: torch.Tensor
    logvar: torch.Tensor
    z: torch.Tensor
    unposed: torch.Tensor | None = None
    offsets: torch.Tensor | None = None


def _checked(field: str, arrays, shapes, expected: str) -> tuple[torch.Tensor, ...]:
    """A decoder's given arrays as float32 tensors, each of its shape in ``shapes``.

    Raises:
        LoosefitInputError: another shape, naming ``field``, ``expected`` and what was found.
    """
    out = tuple(torch.as_tensor(np.asarray(a)).float() for a in arrays)
    if len(out) != len(shapes) or any(t.shape != s for t, s in zip(out, shapes, strict=False)):
        found = ", ".join(str(tuple(t.shape)) for t in out)
        raise LoosefitInputError("GarmentGenerativeModel", field, expected, found)
    return out


class GarmentGenerativeModel(nn.Module):
    """The VAE of paper 3.2 on one garment (its template and UV layout).

    Args:
        template: the garment at rest; ``vertices`` are the canonical shape T.
        config: sizes and the decoder kind.
        ssdr: decoder "ssdr" only: the rest shape (V, 3) and weights (V, B) of a
            skinning decomposition, and the mean bone transforms (B, 3, 4) the
            linear decoder starts from.
        basis: decoder "basis" only: the mean garment (V, 3), the K orthonormal directions
            (K, V, 3) and their coefficients' standard deviations (K,), root frame.
    """

    def __init__(
        self,
        template: GarmentTemplate,
        config: GenerativeConfig | None = None,
        ssdr: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
        basis: tuple[torch.Tensor, torch.Tensor, torch.Tensor] | None = None,
    ) -> None:
        super().__init__()
        self.config = cfg = config or GenerativeConfig()
        self.num_vertices = V = template.num_vertices
        self.uv = UVMap(template, cfg.uv_size)
        self.register_buffer("template", torch.from_numpy(template.vertices.copy()))
        self.encoder = UVEncoder(3, cfg.channels, cfg.uv_size, 2 * cfg.latent)
        if cfg.decoder == "decomposed":
            self.to_static = nn.Linear(cfg.latent, cfg.half)
            self.to_dynamic = nn.Linear(cfg.latent, cfg.half)
            self.rec = _mlp((cfg.half, *cfg.rec_hidden, 3 * V))
            self.dyn = UVDecoder(cfg.half, cfg.channels, cfg.uv_size, 3)
        elif cfg.decoder == "vertex":
            self.dec = UVDecoder(cfg.latent, cfg.channels, cfg.uv_size, 3)
        elif cfg.decoder == "basis":
            self._init_basis(basis, V)
        else:
            if ssdr is None:
                raise LoosefitInputError(
                    "GarmentGenerativeModel", "ssdr", "a skinning decomposition", "None"
                )
            B = np.asarray(ssdr[1]).shape[-1]
            rest, weights, mean = _checked(
                "ssdr",
                ssdr,
                ((V, 3), (V, B), (B, 3, 4)),
                f"rest ({V}, 3), weights ({V}, B), mean transforms (B, 3, 4)",
            )
            self.register_buffer("ssdr_rest", rest)
            self.register_buffer("ssdr_weights", weights)
            self.bones = nn.Linear(cfg.latent, 12 * B)
            nn.init.zeros_(self.bones.weight)
            with torch.no_grad():
                self.bones.bias.copy_(mean.reshape(-1))

    def _init_basis(self, basis, V: int) -> None:
        """Decoder "basis": its buffers, the offset decoder, and the start (the projection)."""
        cfg, K = self.config, self.config.basis_size
        if basis is None:
            raise LoosefitInputError("GarmentGenerativeModel", "basis", "a linear basis", "None")
        mean, dirs, scale = _checked(
            "basis",
            basis,
            ((V, 3), (K, V, 3), (K,)),
            f"mean ({V}, 3), directions ({K}, {V}, 3), scales ({K},)",
        )
        self.register_buffer("basis_mean", mean)
        self.register_buffer("basis_dirs", dirs)
        self.register_buffer("basis_scale", scale)
        self.dyn = UVDecoder(cfg.latent, cfg.channels, cfg.uv_size, 3)
        last = self.dyn.ups[-1][-1]  # the offsets start at zero ...
        nn.init.zeros_(last.weight)
        nn.init.zeros_(last.bias)
        with torch.no_grad():  # ... and the code at the coefficients, a narrow posterior
            self.encoder.fc.weight.zero_()
            self.encoder.fc.bias[: cfg.latent].zero_()
            self.encoder.fc.bias[cfg.latent :].fill_(BASIS_START_LOGVAR)

    # -- the pieces --------------------------------------------------------------

    def encode(self, vertices: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Garments (B, V, 3), root frame, to the posterior's mu and logvar, (B, latent) each."""
        if vertices.ndim != 3 or vertices.shape[1:] != (self.num_vertices, 3):
            raise LoosefitInputError(
                "GarmentGenerativeModel.encode",
                "vertices",
                f"(B, {self.num_vertices}, 3)",
                f"{tuple(vertices.shape)}",
            )
        h = self.encoder(self.uv.encode(vertices))
        mu, logvar = h.chunk(2, dim=-1)
        if self.config.decoder == "basis":  # the basis's coefficients, scaled, plus E_gen's
            K = self.config.basis_size
            c = project(vertices, self.basis_mean, self.basis_dirs) / self.basis_scale
            mu = torch.cat([mu[:, :K] + c, mu[:, K:]], dim=-1)
        return mu, logvar.clamp(-20.0, 10.0)

    def decode(self, z: torch.Tensor) -> dict[str, torch.Tensor]:
        """Codes (B, latent) to ``vertices`` (B, V, 3) (and ``unposed``, ``offsets``)."""
        B, V = z.shape[0], self.num_vertices
        kind = self.config.decoder
        if kind == "decomposed":
            unposed = self.template + self.rec(self.to_static(z)).view(B, V, 3)
            offsets = self.uv.sample(self.dyn(self.to_dynamic(z)))
            return {"vertices": unposed + offsets, "unposed": unposed, "offsets": offsets}
        if kind == "vertex":
            return {"vertices": self.uv.sample(self.dec(z))}
        if kind == "basis":
            offsets = self.uv.sample(self.dyn(z))
            return {"vertices": basis_garment(self, z) + offsets, "offsets": offsets}
        A = self.bones(z).view(B, -1, 3, 4)  # (B, bones, 3, 4)
        posed = torch.einsum("bkij,vj->bvki", A[..., :3], self.ssdr_rest) + A[:, None, :, :, 3]
        return {"vertices": (self.ssdr_weights[None, :, :, None] * posed).sum(2)}

    @torch.no_grad()
    def encode_all(self, vertices: torch.Tensor, chunk: int = 128) -> torch.Tensor:
        """The posterior means (N, latent) of many garments (N, V, 3), ``chunk`` per call,
        on the model's device; returned on the CPU."""
        dev = next(self.parameters()).device
        return torch.cat(
            [
                self.encode(vertices[s : s + chunk].to(dev))[0].cpu()
                for s in range(0, len(vertices), chunk)
            ]
        )

    @torch.no_grad()
    def decode_all(self, z: torch.Tensor, chunk: int = 128) -> torch.Tensor:
        """The garments (N, V, 3) of many codes (N, latent), ``chunk`` per call; on the CPU."""
        dev = next(self.parameters()).device
        return torch.cat(
            [
                self.decode(z[s : s + chunk].to(dev))["vertices"].cpu()
                for s in range(0, len(z), chunk)
            ]
        )

    def reconstruct_all(self, vertices: torch.Tensor, chunk: int = 128) -> torch.Tensor:
        """Encode and decode (the posterior mean) many garments (N, V, 3); on the CPU."""
        return self.decode_all(self.encode_all(vertices, chunk), chunk)

    def forward(
        self, vertices: torch.Tensor, sample: bool | None = None, noise: torch.Tensor | None = None
    ) -> GenerativeOutput:
        """Encode and decode garments (B, V, 3); ``sample`` defaults to ``self.training``;
        ``noise`` (B, latent) is the standard normal draw of the sampling (default: drawn
        here), so that a batch split across processes samples as it would whole."""
        mu, logvar = self.encode(vertices)
        sample = self.training if sample is None else sample
        eps = torch.randn_like(mu) if noise is None else noise.to(mu)
        z = mu + eps * torch.exp(0.5 * logvar) if sample else mu
        out = self.decode(z)
        return GenerativeOutput(
            vertices=out["vertices"],
            mu=mu,
            logvar=logvar,
            z=z,
            unposed=out.get("unposed"),
            offsets=out.get("offsets"),
        )


def basis_garment(model: GarmentGenerativeModel, z: torch.Tensor) -> torch.Tensor:
    """Decoder "basis": the garments (B, V, 3) its basis holds for codes (B, latent)."""
    c = z[:, : model.config.basis_size] * model.basis_scale  # (B, K)
    return reconstruct(c, model.basis_mean, model.basis_dirs)


# -- losses (pure functions) ----------------------------------------------------------


@dataclass
class GenerativeLossConfig:
    """Weights of Eqs. 6-8 (the paper's) and the length unit the squared errors are taken in."""

    laplacian: float = 3.5  # lambda_0
    unposed: float = 0.1  # lambda_1
    template: float = 0.05  # lambda_2
    kl: float = 1.0e-3  # lambda_3
    # Positions are compared in centimetres (x100): in metres the squared errors are
    # ~1e-4 and the KL term at 1e-3 would drown them; the paper does not give its unit.
    length_scale: float = 100.0
    # physics terms of the posed garment (loosefit.model.losses), 0: off
    membrane: float = 0.0  # edge lengths against rest
    bending: float = 0.0  # dihedral angles against rest
    collision: float = 0.0  # cloth outside the body (needs the body's contacts per frame)
    collision_epsilon: float = 0.002  # m

    def __post_init__(self) -> None:
        from loosefit.model.losses import PhysicsLossConfig

        PhysicsLossConfig(self.membrane, self.bending, self.collision, self.collision_epsilon)
        for name in ("laplacian", "unposed", "template", "kl"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise LoosefitInputError("GenerativeLossConfig", name, "a number >= 0", value)


def squared_error(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Mean over vertices (and batch) of the squared Euclidean distance; (..., V, 3) each."""
    return (a - b).pow(2).sum(-1).mean()


def kl_divergence(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """KL(N(mu, exp(logvar)) || N(0, 1)), summed over the latent, mean over the batch."""
    return (-0.5 * (1 + logvar - mu.pow(2) - logvar.exp())).sum(-1).mean()


def generative_loss(
    out: GenerativeOutput,
    target: torch.Tensor,
    target_unposed: torch.Tensor | None,
    template: torch.Tensor,
    laplacian,
    weights: GenerativeLossConfig,
    *,
    structure=None,
    contacts: tuple[torch.Tensor, torch.Tensor] | None = None,
) -> dict[str, torch.Tensor]:
    """Eqs. 6-8: geometry, Laplacian, unposed (inverse skinning), template, KL; and the
    physics terms of the posed garment that ``weights`` turns on (membrane, bending,
    collision; :mod:`loosefit.model.losses`).

    Args:
        out: the model's output for B garments.
        target: (B, V, 3) simulated garments V*, root frame.
        target_unposed: (B, V, 3) their inverse skinning T~* (decomposed model), or None.
        template: (V, 3) the canonical template T.
        laplacian: a callable (B, V, 3) -> (B, V, 3), the mesh Laplacian.
        weights: the lambdas and the length unit.
        structure: the garment's :class:`~loosefit.model.losses.ClothStructure` (for the
            physics terms).
        contacts: (B, V, 3) body points and normals of every vertex, root frame (for the
            collision term).

    Returns:
        The terms (already weighted) and their sum under ``"total"``.
    """
    s = weights.length_scale
    terms = {
        "geometry": squared_error(s * out.vertices, s * target),
        "laplacian": weights.laplacian
        * squared_error(s * laplacian(out.vertices), s * laplacian(target)),
        "kl": weights.kl * kl_divergence(out.mu, out.logvar),
    }
    if out.unposed is not None:
        if target_unposed is not None:
            terms["unposed"] = weights.unposed * squared_error(s * out.unposed, s * target_unposed)
        terms["template"] = weights.template * squared_error(s * out.unposed, s * template)
    if weights.membrane > 0 or weights.bending > 0 or weights.collision > 0:
        from loosefit.model.losses import physics_terms

        if structure is None:
            raise ValueError("the physics terms need the garment's ClothStructure")
        for k, v in physics_terms(out.vertices, structure, weights, contacts, s).items():
            terms[k] = v.mean()
    terms["total"] = sum(terms.values())
    return terms
