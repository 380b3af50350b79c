"""Detail enhancement (paper 3.4): an EdgeConv generator and a multi-scale patch discriminator.

The generator ``G_de`` reads the decoded garment ``V_t`` (root frame) through three
EdgeConv layers (Wang et al. 2019: per vertex ``max_j h(x_i || x_j - x_i)`` over its
mesh neighbours; :class:`MeshEdgeConv` computes ``torch_geometric.nn.EdgeConv`` with
``aggr="max"`` and a one-layer edge MLP exactly, from per-vertex products and a
padded neighbour table, with the same parameters) and the latent code ``Z_t``
through two fully connected layers, concatenates the two per vertex and maps them
by one fully connected layer to an offset ``I_de``: ``V_f = V_t + I_de``. Its last
layer starts at zero, so an untrained module changes nothing.

The discriminator ``D_ms`` judges UV maps of garments (paper 3.2's ``S``) in
patches at three scales (64, 32 and 16 texels by default): the map is cut into
non-overlapping square patches of each size, each patch centred on its mean
position (the discriminator judges the shape of neighbouring deformations, not
where they are), and one patch network per scale (four stride-2 convolutions,
instance norm, leaky ReLU) scores every patch. Losses (pure functions below):
Eq. 13 (L1 on positions and on the Laplacian) and the least-squares adversarial
loss of Eq. 14.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from loosefit.errors import LoosefitInputError
from loosefit.geometry.edges import unique_edges


@dataclass
class DetailConfig:
    """Sizes of the detail generator and discriminator (the paper's, where it gives them)."""

    edge_channels: tuple[int, ...] = (3, 8, 10)  # the three EdgeConv layers' vertex features
    global_hidden: tuple[int, ...] = (64, 32)  # the two FC layers on Z_t
    patches: tuple[int, ...] = (64, 32, 16)  # D_ms: patch sizes in texels, one network each
    disc_channels: tuple[int, ...] = (32, 64, 128)  # D_ms: the first three convolutions' widths
    slope: float = 0.2  # leaky ReLU
    scale: float = 10.0  # positions enter in decimetres; offsets come out in 1/scale m

    def __post_init__(self) -> None:
        self.edge_channels = tuple(int(c) for c in self.edge_channels)
        self.global_hidden = tuple(int(c) for c in self.global_hidden)
        self.patches = tuple(int(c) for c in self.patches)
        self.disc_channels = tuple(int(c) for c in self.disc_channels)
        if not self.edge_channels or min(self.edge_channels) < 1:
            raise LoosefitInputError(
                "DetailConfig", "edge_channels", "positive widths", self.edge_channels
            )
        if len(self.global_hidden) != 2 or min(self.global_hidden) < 1:
            raise LoosefitInputError(
                "DetailConfig", "global_hidden", "two positive widths", self.global_hidden
            )
        if len(self.disc_channels) != 3:
            raise LoosefitInputError(
                "DetailConfig", "disc_channels", "three widths", self.disc_channels
            )
        for s in self.patches:
            if s < 16 or s & (s - 1):
                raise LoosefitInputError("DetailConfig", "patches", "powers of two >= 16", s)


def mesh_edge_index(faces: np.ndarray | torch.Tensor) -> torch.Tensor:
    """(2, 2E) int64 directed edges (both directions) of a triangle mesh (F, 3), each once."""
    e = torch.from_numpy(unique_edges(np.asarray(faces))[0])  # (E, 2)
    return torch.cat([e, e.flip(1)]).t().contiguous()


def neighbour_table(edge_index: torch.Tensor, num_vertices: int) -> torch.Tensor:
    """(V, K) int64: each vertex's neighbours (sources j of edges j -> i), K the largest
    valence; shorter rows repeat their first neighbour (a max does not see repeats).

    Raises:
        LoosefitInputError: a vertex without any edge.
    """
    src, dst = edge_index
    order = torch.argsort(dst, stable=True)
    src, dst = src[order], dst[order]
    count = torch.bincount(dst, minlength=num_vertices)  # (V,)
    if int(count.min()) == 0:
        lonely = int(torch.nonzero(count == 0)[0])
        raise LoosefitInputError(
            "garment mesh", "faces", "every vertex in a triangle", f"vertex {lonely} in none"
        )
    K = int(count.max())
    start = torch.cumsum(count, 0) - count  # (V,)
    slot = torch.arange(len(dst)) - start[dst]  # position of each edge in its row
    table = src[start][:, None].repeat(1, K)  # (V, K): the first neighbour everywhere
    table[dst, slot] = src
    return table


class MeshEdgeConv(nn.Module):
    """``torch_geometric.nn.EdgeConv(nn, aggr="max")`` on one fixed mesh, for an edge
    MLP of one linear layer and a leaky ReLU (the generator's).

    ``x'_i = max_j act(W [x_i || x_j - x_i] + b)`` over the mesh neighbours j of i.
    With ``W = [W1 W2]`` the argument is ``(W1 - W2) x_i + b + W2 x_j``, and a leaky
    ReLU is increasing, so ``x'_i = act((W1 - W2) x_i + b + max_j W2 x_j)``: two
    per-vertex products and a max over a (V, K) neighbour table, instead of the MLP on
    every edge. Same parameters (``nn``) and result as torch_geometric's layer.

    Args:
        nn: ``Sequential(Linear(2 C_in, C_out), LeakyReLU)``.
        table: (V, K) from :func:`neighbour_table`.
    """

    def __init__(self, nn: nn.Sequential, table: torch.Tensor) -> None:
        super().__init__()
        self.nn = nn
        self.register_buffer("table", table, persistent=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, V, C_in) -> (B, V, C_out)."""
        linear, act = self.nn
        B, V, C = x.shape
        w1, w2 = linear.weight[:, :C], linear.weight[:, C:]
        own = x @ (w1 - w2).t() + linear.bias  # (B, V, C_out)
        other = x @ w2.t()  # (B, V, C_out)
        K = self.table.shape[1]
        best = other[:, self.table.reshape(-1)].reshape(B, V, K, -1).max(dim=2).values
        return act(own + best)


class DetailGenerator(nn.Module):
    """``G_de``: (V_t, Z_t) to the offset ``I_de``.

    Args:
        faces: (F, 3) the garment's triangles (the EdgeConv graph).
        num_vertices: V.
        latent: the size of Z_t.
        config: the sizes.
    """

    def __init__(
        self, faces: np.ndarray, num_vertices: int, latent: int, config: DetailConfig | None = None
    ) -> None:
        super().__init__()
        self.config = cfg = config or DetailConfig()
        self.num_vertices = num_vertices
        self.latent = latent
        self.register_buffer("edge_index", mesh_edge_index(faces), persistent=False)
        table = neighbour_table(self.edge_index, num_vertices)
        convs, cin = [], 3
        for cout in cfg.edge_channels:
            mlp = nn.Sequential(nn.Linear(2 * cin, cout), nn.LeakyReLU(cfg.slope))
            convs.append(MeshEdgeConv(mlp, table))
            cin = cout
        self.convs = nn.ModuleList(convs)
        h1, h2 = cfg.global_hidden
        self.globals = nn.Sequential(
            nn.Linear(latent, h1),
            nn.LeakyReLU(cfg.slope),
            nn.Linear(h1, h2),
            nn.LeakyReLU(cfg.slope),
        )
        self.out = nn.Linear(cin + h2, 3)
        nn.init.zeros_(self.out.weight)
        nn.init.zeros_(self.out.bias)

    def forward(self, vertices: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        """Garments (B, V, 3) in their root frames and codes (B, latent) to offsets (B, V, 3)."""
        B, V = vertices.shape[0], self.num_vertices
        if vertices.ndim != 3 or vertices.shape[1:] != (V, 3):
            raise LoosefitInputError(
                "DetailGenerator", "vertices", f"(B, {V}, 3)", f"{tuple(vertices.shape)}"
            )
        if z.shape != (B, self.latent):
            raise LoosefitInputError(
                "DetailGenerator", "z", f"({B}, {self.latent})", f"{tuple(z.shape)}"
            )
        h = vertices * self.config.scale  # (B, V, 3)
        for conv in self.convs:
            h = conv(h)  # (B, V, C)
        g = self.globals(z)[:, None].expand(-1, V, -1)  # (B, V, h2)
        return self.out(torch.cat([h, g], -1)) / self.config.scale  # (B, V, 3)


class PatchDiscriminator(nn.Module):
    """Four stride-2 convolutions: patches (N, 3, s, s) to scores (N, 1, s/16, s/16).

    The first convolution has no norm (as in PatchGAN) and the last is the score
    (no norm or activation); the two between use instance norm.
    """

    def __init__(self, channels: tuple[int, ...], slope: float) -> None:
        super().__init__()
        c1, c2, c3 = channels
        self.net = nn.Sequential(
            nn.Conv2d(3, c1, 4, 2, 1),
            nn.LeakyReLU(slope),
            nn.Conv2d(c1, c2, 4, 2, 1),
            nn.InstanceNorm2d(c2, affine=True),
            nn.LeakyReLU(slope),
            nn.Conv2d(c2, c3, 4, 2, 1),
            nn.InstanceNorm2d(c3, affine=True),
            nn.LeakyReLU(slope),
            nn.Conv2d(c3, 1, 4, 2, 1),
        )

    def forward(self, patches: torch.Tensor) -> torch.Tensor:
        return self.net(patches)


def cut_patches(maps: torch.Tensor, size: int) -> torch.Tensor:
    """UV maps (B, C, H, W) to non-overlapping patches (B * H/size * W/size, C, size, size),
    each centred on its mean (per channel)."""
    B, C, H, W = maps.shape
    if H % size or W % size:
        raise LoosefitInputError("cut_patches", "size", f"a divisor of the map's {H}x{W}", size)
    p = maps.unfold(2, size, size).unfold(3, size, size)  # (B, C, H/s, W/s, s, s)
    p = p.permute(0, 2, 3, 1, 4, 5).reshape(-1, C, size, size)  # (N, C, s, s)
    return p - p.mean(dim=(2, 3), keepdim=True)


class MultiScaleDiscriminator(nn.Module):
    """``D_ms``: one :class:`PatchDiscriminator` per patch size, over the same UV maps.

    Args:
        uv_size: H = W of the maps (every patch size must divide it).
        config: the patch sizes and widths.
    """

    def __init__(self, uv_size: int, config: DetailConfig | None = None) -> None:
        super().__init__()
        self.config = cfg = config or DetailConfig()
        for s in cfg.patches:
            if s > uv_size or uv_size % s:
                raise LoosefitInputError(
                    "MultiScaleDiscriminator",
                    "patches",
                    f"sizes dividing the {uv_size}-texel map",
                    s,
                )
        self.nets = nn.ModuleList(
            PatchDiscriminator(cfg.disc_channels, cfg.slope) for _ in cfg.patches
        )

    def forward(self, maps: torch.Tensor) -> list[torch.Tensor]:
        """UV maps (B, 3, H, W) of garments (m) to one score tensor per scale,
        (B * patches, 1, s/16, s/16)."""
        x = maps * self.config.scale
        return [
            net(cut_patches(x, s)) for s, net in zip(self.config.patches, self.nets, strict=True)
        ]


# -- losses (pure functions) ------------------------------------------------------------


def detail_geometry_loss(
    pred: torch.Tensor,
    target: torch.Tensor,
    laplacian,
    length_scale: float = 100.0,
    laplacian_weight: float = 1.0,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Eq. 13: mean L1 of positions and of Laplacians, in ``1/length_scale`` m (cm).

    Args:
        pred, target: (B, V, 3) garments (m).
        laplacian: a callable (B, V, 3) -> (B, V, 3), the mesh Laplacian.
        length_scale: metres to the loss's unit.
        laplacian_weight: the Laplacian term's weight.

    Returns:
        The position term and the (weighted) Laplacian term, scalars.
    """
    s = length_scale
    position = (s * (pred - target)).abs().sum(-1).mean()
    lap = (s * (laplacian(pred) - laplacian(target))).abs().sum(-1).mean()
    return position, laplacian_weight * lap


def edge_length_loss(
    pred: torch.Tensor, target: torch.Tensor, edges: torch.Tensor, length_scale: float = 100.0
) -> torch.Tensor:
    """Mean L1 of edge lengths against the target's, in ``1/length_scale`` m (cm).

    Not in the paper's Eq. 13: positions and Laplacians leave the lengths of single
    edges free, and an edge stretched one way and its neighbour squeezed the other is
    what makes a garment read as crumpled (edge strain).

    Args:
        pred, target: (B, V, 3) garments (m).
        edges: (2, E) vertex pairs, each edge once.
        length_scale: metres to the loss's unit.

    Returns:
        A scalar.
    """
    a, b = edges

    def lengths(x: torch.Tensor) -> torch.Tensor:
        return (x[:, a] - x[:, b]).norm(dim=-1)  # (B, E)

    return (length_scale * (lengths(pred) - lengths(target))).abs().mean()


def lsgan_discriminator_loss(real: list[torch.Tensor], fake: list[torch.Tensor]) -> torch.Tensor:
    """Eq. 14 for ``D_ms``: ``E[(D(S*) - 1)^2] + E[(D(S_f) + 1)^2]``, averaged over scales."""
    terms = [(r - 1).pow(2).mean() + (f + 1).pow(2).mean() for r, f in zip(real, fake, strict=True)]
    return torch.stack(terms).mean()


def lsgan_generator_loss(fake: list[torch.Tensor]) -> torch.Tensor:
    """Eq. 14 for ``G_de``: ``E[(D(S_f) - 1)^2]`` (its fakes judged real), averaged over scales."""
    return torch.stack([(f - 1).pow(2).mean() for f in fake]).mean()
