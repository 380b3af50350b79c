"""The GPU side of one mesh in the renderer: its buffers, and setting shader uniforms.

A :class:`GpuMesh` holds the vertex, normal, colour and index buffers of one scene slot of
:class:`~loosefit.render.renderer.Renderer` and rewrites only what changed from one frame
to the next; :func:`set_uniform` and :func:`write_uniform_matrix` set a program's uniforms,
skipping those the GLSL compiler dropped.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from loosefit.render.renderer import RGB, RenderMesh


class GpuMesh:
    """Persistent GPU buffers of one scene slot; per-frame updates are buffer writes only."""

    def __init__(
        self, ctx, mesh_prog, shadow_prog, num_vertices: int, num_faces: int, two_sided: bool
    ) -> None:
        self.size = (num_vertices, num_faces, two_sided)
        self.two_sided = two_sided
        self.pos = ctx.buffer(reserve=num_vertices * 12)
        self.nrm = ctx.buffer(reserve=num_vertices * 12)
        self.col = ctx.buffer(reserve=num_vertices * 12)
        self.ibo = ctx.buffer(reserve=num_faces * 12)
        self.vao = ctx.vertex_array(
            mesh_prog,
            [
                (self.pos, "3f", "in_pos"),
                (self.nrm, "3f", "in_normal"),
                (self.col, "3f", "in_color"),
            ],
            index_buffer=self.ibo,
            index_element_size=4,
        )
        self.shadow_vao = ctx.vertex_array(
            shadow_prog, [(self.pos, "3f", "in_pos")], index_buffer=self.ibo, index_element_size=4
        )
        # What the buffers hold now; the arrays are kept alive so identity checks are safe.
        self.faces_src: np.ndarray | None = None
        self.vert_src: tuple[np.ndarray, int] | None = None
        self.color_src: tuple[object, int] | None = None

    def sync(self, mesh: RenderMesh, t: int, color: RGB) -> None:
        """Write frame ``t`` of ``mesh`` into the buffers (skipping what is already there)."""
        if self.faces_src is not mesh.faces:
            self.ibo.write(mesh.faces.astype(np.int32).tobytes())
            self.faces_src = mesh.faces
        tv = t if mesh.num_frames > 1 else 0
        if self.vert_src is None or self.vert_src[0] is not mesh.vertices or self.vert_src[1] != tv:
            pos = mesh.vertices[tv]  # (V, 3)
            self.pos.write(pos.tobytes())
            self.nrm.write(mesh._plan(pos).astype(np.float32).tobytes())
            self.vert_src = (mesh.vertices, tv)
        vc = mesh.vertex_colors
        key: tuple[object, int] = (color, 0) if vc is None else (vc, t if len(vc) > 1 else 0)
        if self.color_src is None or self.color_src[0] is not key[0] or self.color_src[1] != key[1]:
            if vc is None:
                data = np.tile(np.asarray(color, np.float32), (mesh.num_vertices, 1))  # (V, 3)
            else:
                data = vc[key[1]]
            self.col.write(np.ascontiguousarray(data, dtype=np.float32).tobytes())
            self.color_src = key

    def release(self) -> None:
        for obj in (self.vao, self.shadow_vao, self.pos, self.nrm, self.col, self.ibo):
            obj.release()


def write_uniform_matrix(prog, name: str, m: np.ndarray) -> None:
    """Set the (4, 4) matrix uniform ``name`` of ``prog`` (column-major, as GLSL reads it)."""
    if name in prog:
        prog[name].write(np.ascontiguousarray(m.T, dtype=np.float32).tobytes())


def set_uniform(prog, name: str, value) -> None:
    """Set the uniform ``name`` of ``prog``, if the program has it."""
    if name in prog:  # the GLSL compiler drops unused uniforms
        prog[name].value = value
