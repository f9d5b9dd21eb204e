"""Sobol generator matrices, computed from the published primitive polynomials and initial
direction numbers of Joe and Kuo (2008, the ``new-joe-kuo-6.21201`` set), and the constant table
the kernels read (``SOBOL_MATRIX``, appended to the generated header by :func:`abi.cl_header`).

Dimension 0 is the van der Corput sequence (the identity matrix on bit-reversed indices).
Dimension d >= 1 uses the primitive polynomial x^s + a_1 x^(s-1) + ... + a_(s-1) x + 1 of degree
s (``a`` holds a_1 ... a_(s-1) as bits, a_1 the highest) and the odd initial numbers m_1 .. m_s
(m_k < 2^k); later ones follow the recurrence

    m_k = 2 a_1 m_(k-1)  ^  4 a_2 m_(k-2)  ^ ... ^  2^(s-1) a_(s-1) m_(k-s+1)  ^  2^s m_(k-s)  ^  m_(k-s)

and column k (1-based) of the 32-bit matrix is v_k = m_k * 2^(32-k): index bit k-1 set XORs v_k
into the 32-bit fixed-point coordinate.

The kernels only need dimensions 0 and 1: every pair of random dimensions is its own Owen-
scrambled 2D (0,2)-sequence, padded as pbrt-v4's ZSobol sampler does (cl/render/sampler.h), so
the header holds :data:`KERNEL_DIMS` of them.  The rest of the table is there for the tests.
"""
from __future__ import annotations

import numpy as np

BITS = 32
# (degree s, coefficients a, initial m_1..m_s) of dimensions 1, 2, ... (Joe & Kuo's d = 2, 3, ...)
JOE_KUO = (
    (1, 0, (1,)),
    (2, 1, (1, 3)),
    (3, 1, (1, 3, 1)),
    (3, 2, (1, 1, 1)),
    (4, 1, (1, 1, 3, 3)),
    (4, 4, (1, 3, 5, 13)),
    (5, 2, (1, 1, 5, 5, 17)),
)
KERNEL_DIMS = 2


def direction_numbers(dim: int, count: int = BITS) -> list[int]:
    """m_1 .. m_count of dimension ``dim`` (>= 1)."""
    s, a, m = JOE_KUO[dim - 1]
    m = list(m)
    for k in range(s, count):  # m[k] is m_(k+1)
        value = m[k - s] ^ (m[k - s] << s)
        for j in range(1, s):
            if (a >> (s - 1 - j)) & 1:
                value ^= m[k - j] << j
        m.append(value)
    return m[:count]


def generator_matrix(dim: int) -> np.ndarray:
    """The BITS columns of dimension ``dim`` as uint32: column k is what index bit k contributes."""
    if dim == 0:
        return np.array([1 << (BITS - 1 - k) for k in range(BITS)], np.uint32)
    m = direction_numbers(dim)
    return np.array([m[k] << (BITS - 1 - k) for k in range(BITS)], np.uint32)


def cl_table(dims: int = KERNEL_DIMS) -> str:
    """``__constant uint SOBOL_MATRIX[dims][32]`` for the generated header."""
    rows = ",\n".join("    {" + ", ".join(f"0x{int(c):08x}u" for c in generator_matrix(d)) + "}" for d in range(dims))
    return (f"/* Sobol generator matrices (pyopencl_rt/device/sobol.py): column k = index bit k */\n"
            f"__constant uint SOBOL_MATRIX[{dims}][{BITS}] = {{\n{rows}\n}};\n")
