"""Setting shader uniforms: matrices go column-major, uniforms the program lacks are skipped."""

import numpy as np

from loosefit.render.gpu import set_uniform, write_uniform_matrix


class _Uniform:
    def __init__(self) -> None:
        self.value = None
        self.written = None

    def write(self, data: bytes) -> None:
        self.written = data


def test_a_matrix_is_written_transposed_as_float32_and_missing_uniforms_are_skipped():
    prog = {"u_vp": _Uniform(), "u_eye": _Uniform()}
    m = np.arange(16, dtype=np.float64).reshape(4, 4)  # row-major in numpy
    write_uniform_matrix(prog, "u_vp", m)
    got = np.frombuffer(prog["u_vp"].written, np.float32)
    # GLSL reads column by column: the first four floats are the first column
    assert got[:4].tolist() == [0.0, 4.0, 8.0, 12.0]
    np.testing.assert_array_equal(got.reshape(4, 4).T, m)
    set_uniform(prog, "u_eye", (1.0, 2.0, 3.0))
    assert prog["u_eye"].value == (1.0, 2.0, 3.0)
    write_uniform_matrix(prog, "u_gone", m)  # dropped by the GLSL compiler: nothing happens
    set_uniform(prog, "u_gone", 1.0)
    assert set(prog) == {"u_vp", "u_eye"}
