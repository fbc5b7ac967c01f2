"""The cross product is one law (issue 14): ``fawtgym.core.so3_kernels.cross_entries``.

* its forms (the row helper ``cross_row``, the numpy-facing ``core.so3.cross``) are that law, so they agree with it
  and with each other bitwise (one code path, no tolerance), special values included; ``numpy.cross`` does the same
  operations in the same order, so it agrees bitwise too;
* the rigid-body helpers built on it (the gyroscopic term, the known angular acceleration of Wang et al. (2024)
  eq. 38) are bitwise what the observers' row helper returns, and agree with the numpy reference
  ``observers.gibbs.rigid_body_rhs`` (``np.linalg.inv`` and ``einsum``: another implementation, so a tolerance);
* no module outside ``core/so3_kernels.py`` writes a cross product out componentwise (a source scan: on the
  previous main it finds the ten hand-written copies in envs/ and observers/ and core's own second copy).
"""

import pathlib
import re

import numpy as np
from _tolerance import assert_same_law

from fawtgym.core import so3_kernels as k
from fawtgym.core.so3 import cross
from fawtgym.observers._obs_common import known_angular_acceleration_row
from fawtgym.observers.gibbs import rigid_body_rhs

ROOT = pathlib.Path(__file__).resolve().parents[1]
J = np.array([[0.03, 0.001, -0.002], [0.001, 0.031, 0.0005], [-0.002, 0.0005, 0.05]])


def _vectors(rng, n=200):
    v = rng.normal(size=(n, 3)) * np.exp(3.0 * rng.normal(size=(n, 1)))
    v[:3] = 0.0
    v[3] = -0.0
    v[4] = [1.0, 1.0, 1.0]
    v[5] = [np.inf, 0.0, 1.0]
    v[6] = [np.nan, 1.0, -1.0]
    v[7] = [1e308, -1e308, 3.0]
    return v


def _bits(x):
    return np.ascontiguousarray(x, dtype=np.float64).view(np.uint64)


def test_cross_forms_are_one_law_bitwise():
    rng = np.random.default_rng(0)
    a, b = _vectors(rng), _vectors(rng)[::-1].copy()
    entries = np.array([k.cross_entries(*a[i], *b[i]) for i in range(len(a))])
    rows = np.empty_like(a)
    for i in range(len(a)):
        k.cross_row(a[i], b[i], rows[i])
    with np.errstate(invalid="ignore", over="ignore"):
        reference = np.cross(a, b)
        np.testing.assert_array_equal(_bits(rows), _bits(entries))
        np.testing.assert_array_equal(_bits(cross(a, b)), _bits(entries))
        np.testing.assert_array_equal(_bits(reference), _bits(entries))
        # broadcast over leading axes, and a single vector against a batch
        np.testing.assert_array_equal(cross(a[:20, None], b[None, :7]), np.cross(a[:20, None], b[None, :7]))
        np.testing.assert_array_equal(cross(a[8], b[8:30]), np.cross(a[8], b[8:30]))
    # the definition: anticommutative, orthogonal to its operands, e1 x e2 = e3 (finite rows)
    fa, fb = a[8:-8], b[8:-8]
    c = cross(fa, fb)
    np.testing.assert_array_equal(cross(fb, fa), -c)
    assert cross([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]).tolist() == [0.0, 0.0, 1.0]
    na, nb = np.abs(fa).max(axis=1), np.abs(fb).max(axis=1)
    assert (np.abs((c * fa).sum(axis=1)) <= 1e-14 * na * na * nb).all()
    assert (np.abs((c * fb).sum(axis=1)) <= 1e-14 * na * nb * nb).all()


def test_cross_row_may_alias_its_operands():
    a, b = np.array([0.3, -1.2, 2.0]), np.array([1.5, 0.25, -0.7])
    expected = cross(a, b)
    k.cross_row(a, b, a)
    np.testing.assert_array_equal(a, expected)


def test_rigid_body_helpers():
    rng = np.random.default_rng(1)
    w, tau = rng.normal(size=(100, 3)) * 5.0, rng.normal(size=(100, 3)) * 0.1
    j_inv = np.linalg.inv(J)
    gyro = np.array([k.gyroscopic_entries(J, *w[i]) for i in range(len(w))])
    # (J w) x w against numpy's matmul (BLAS sums in its own order: another implementation, a tolerance)
    assert_same_law(gyro, cross(w @ J.T, w), scale=np.abs(J).max() * np.abs(w).max() ** 2, what="(J w) x w")
    swapped = np.array([k.cross_entries(*w[i], *k.mat_vec_entries(J, *w[i])) for i in range(len(w))])
    np.testing.assert_array_equal(swapped, -gyro)                                 # w x (J w), ctbr's feedforward
    known = np.array([k.known_angular_acceleration_entries(J, j_inv, *w[i], *tau[i]) for i in range(len(w))])
    row = np.empty(3)
    for i in range(len(w)):
        known_angular_acceleration_row(w[i], tau[i], J, j_inv, row)
        np.testing.assert_array_equal(row, known[i])                              # the observers' row helper
    assert_same_law(known, rigid_body_rhs(w, J, tau), scale=np.abs(known).max(), what="J^-1 (J w x w + tau)")
    # Euler's equation: J w' = J w x w + tau
    assert_same_law(known @ J.T, gyro + tau, scale=np.abs(gyro).max() + np.abs(tau).max(), what="J w'")


# written-out cross-product components: a_j b_k - a_k b_j over names ending in the index (a1, jw2) or indexed by a
# constant (a[1], a[..., 2]); the row index of a 2-D array (r[i, 0], e[2, 1]) is not a vector component
_COMPONENT = re.compile(r"\b([A-Za-z_]\w*?)(?:\[(?:\.\.\., )?([012])\]|([012]))(?![\w\[])")
_CROSS = re.compile(r"(\w+)#([012]) \* (\w+)#([012]) - \1#\4 \* \3#\2")


def _written_out_crosses(path: pathlib.Path, root: pathlib.Path = ROOT) -> list[str]:
    found = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        norm = _COMPONENT.sub(lambda m: f"{m.group(1)}#{m.group(2) or m.group(3)}", line)
        if any(m.group(2) != m.group(4) for m in _CROSS.finditer(norm)):
            found.append(f"{path.relative_to(root)}:{n}: {line.strip()}")
    return found


def test_the_scan_finds_a_written_out_cross(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text("x = a1 * b2 - a2 * b1\ny = u[2] * v[0] - u[0] * v[2]\nz = p[..., 0] * q[..., 1] - p[..., 1] * "
                      "q[..., 0]\nok = r[i, 1] * s[2] - r[i, 2] * s[1]\nsq = a1 * a1 - b1 * b1\n")
    found = [int(hit.split(":")[1]) for hit in _written_out_crosses(sample, root=tmp_path)]
    assert found == [1, 2, 3], found


def test_no_cross_product_written_out_outside_core():
    law = ROOT / "fawtgym" / "core" / "so3_kernels.py"
    files = [p for top in ("fawtgym", "envs", "observers", "agents", "eval", "train")
             for p in sorted((ROOT / top).rglob("*.py")) if p != law]
    assert len(files) > 50
    found = [hit for p in files for hit in _written_out_crosses(p)]
    assert not found, "cross products written out (use fawtgym.core.so3_kernels.cross_entries):\n" + "\n".join(found)
    assert len(_written_out_crosses(law)) == 1                                    # the law itself, once
