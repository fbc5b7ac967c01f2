"""Dryden turbulence, the spec: MIL-F-8785C and MIL-HDBK-1797 parameters, spectra and spatial shaping filters.

The gust velocities (u along the mean relative air flow, v lateral, w vertical) are white noise
passed through the Dryden shaping filters.  The filters are realized **in the spatial domain**
(Taylor's frozen turbulence: the field is a function of the distance ``xi`` the air has travelled
past the vehicle), with ``Omega`` the spatial frequency [rad/m] and ``s_x`` the spatial Laplace
variable [1/m].  With unit-intensity white noise ``n(xi)`` the filters are ``|H(j Omega)|^2 =
pi Phi(Omega)``, where ``Phi`` is the one-sided spatial PSD of the spec (``int_0^inf Phi dOmega =
sigma^2``):

* MIL-F-8785C (and MIL-HDBK-1797, same ``u``)::

      Phi_u = sigma_u^2 (2 L_u / pi) / (1 + (L_u Omega)^2)
      H_u   = sigma_u sqrt(2 L_u) / (1 + L_u s_x)
      Phi_v = sigma_v^2 (L_v / pi) (1 + 3 (L_v Omega)^2) / (1 + (L_v Omega)^2)^2
      H_v   = sigma_v sqrt(L_v) (1 + sqrt(3) L_v s_x) / (1 + L_v s_x)^2

* MIL-HDBK-1797 lateral/vertical (its ``L_v`` is half the 8785C one for the same field)::

      Phi_v = sigma_v^2 (2 L_v / pi) (1 + 12 (L_v Omega)^2) / (1 + 4 (L_v Omega)^2)^2
      H_v   = sigma_v sqrt(2 L_v) (1 + 2 sqrt(3) L_v s_x) / (1 + 2 L_v s_x)^2

  (``w`` as ``v`` with ``L_w``, ``sigma_w``.)

* Optional gust gradients (the "rotational" p, q, r components, MIL-F-8785C, span ``b``)::

      Phi_p = sigma_w^2 0.8 (pi / (4 b))^(1/3) L_w^(-2/3) / (1 + (4 b Omega / pi)^2)    (p = dw/dy)
      q = s_x / (1 + (4 b / pi) s_x) w          r = s_x / (1 + (3 b / pi) s_x) v        (dw/dxi, dv/dxi)

  These assume ``L >> b``; they are off by default.

The filters are realized in the spatial domain so that they do not depend on the airspeed ``V``:
the exact step over a distance ``d = V dt`` is :mod:`.dryden_discrete`, the N independent processes that
step them are :mod:`.dryden_process`.  This module holds the spec: parameters, spectra, filters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from fawtgym.core.checks import check_number, check_positive, shown

FORMS = ("8785c", "1797")
#: Lower bound of the frozen-turbulence speed [m/s].  Below ~1 m/s Taylor's hypothesis does not hold
#: and L/V would freeze the gusts of a vehicle hovering in still mean air; 1 m/s keeps the time
#: scale finite (MATLAB's Dryden block has no floor and divides by zero at V = 0).
V_FLOOR = 1.0


#: Gust length scales [m] the filters take: from a wind tunnel's centimetre eddies (FAWT 0.02 m) to beyond the
#: MIL-spec's 533 m at 1000 ft; outside, the filter poles V / L under- or overflow the step matrices.
LENGTH_SCALE_RANGE = (1e-3, 1e5)
#: Vehicle spans [m] for the gust-gradient (``rates``) filters: a micro quad to a large airframe.
SPAN_RANGE = (1e-3, 100.0)


def check_length_scale(name: str, value: float) -> float:
    """A gust length scale [m] in :data:`LENGTH_SCALE_RANGE` (one-line ValueError naming ``name`` otherwise)."""
    return check_number(value, name, minimum=LENGTH_SCALE_RANGE[0], maximum=LENGTH_SCALE_RANGE[1],
                        inclusive_minimum=True, note="m")


@dataclass(frozen=True)
class DrydenParams:
    """Intensities [m/s] and length scales [m] of the three gust components, in one spec form.

    ``form`` is ``"8785c"`` or ``"1797"``: the length scales are *that* form's (``L_v``, ``L_w`` of
    MIL-HDBK-1797 are half those of MIL-F-8785C for the same turbulence).  ``span`` [m] sets the
    gust-gradient filters (used only with ``rates=True``).
    """

    sigma: tuple[float, float, float]
    length: tuple[float, float, float]
    form: str = "8785c"
    span: float = 0.5

    def __post_init__(self) -> None:
        if self.form not in FORMS:
            raise ValueError(f"Dryden form must be one of {FORMS}, got {shown(self.form)}")
        sig = tuple(check_number(s, f"turbulence intensity sigma_{c}", minimum=0.0, inclusive_minimum=True, note="m/s")
                    for c, s in zip("uvw", self.sigma, strict=True))
        lens = tuple(check_length_scale(f"length scale L_{c}", s) for c, s in zip("uvw", self.length, strict=True))
        object.__setattr__(self, "sigma", sig)
        object.__setattr__(self, "length", lens)
        object.__setattr__(self, "span", check_number(self.span, "span", minimum=SPAN_RANGE[0],
                                                      maximum=SPAN_RANGE[1], inclusive_minimum=True, note="m"))


def dryden_psd(params: DrydenParams, component: str, freq_hz: NDArray[np.float64] | float,
               airspeed: float) -> NDArray[np.float64]:
    """Analytic one-sided temporal PSD [(m/s)^2/Hz] of ``component`` in ``"uvw"`` at ``freq_hz``.

    ``G(f) = 2 pi Phi(Omega = 2 pi f / V) / V`` so that ``int_0^inf G df = sigma^2``; this is what
    ``scipy.signal.welch`` (``scaling="density"``, one-sided) estimates.
    """
    f = np.asarray(freq_hz, dtype=float)
    v = check_positive(airspeed, "airspeed", note="m/s")
    i = "uvw".index(component)
    sig, length = params.sigma[i], params.length[i]
    om = 2.0 * math.pi * f / v
    if component == "u":
        phi = sig**2 * 2.0 * length / math.pi / (1.0 + (length * om) ** 2)
    elif params.form == "8785c":
        x = (length * om) ** 2
        phi = sig**2 * length / math.pi * (1.0 + 3.0 * x) / (1.0 + x) ** 2
    else:
        x = (length * om) ** 2
        phi = sig**2 * 2.0 * length / math.pi * (1.0 + 12.0 * x) / (1.0 + 4.0 * x) ** 2
    return 2.0 * math.pi * phi / v


def _second_order(sig: float, gain_len: float, zero: float, pole: float) -> tuple[NDArray, NDArray, NDArray]:
    """Realization of ``sig sqrt(gain_len) (1 + zero s) / (1 + pole s)^2`` as two first-order lags in series.

    ``z1' = (n - z1) / pole``, ``z2' = (z1 - z2) / pole``, ``y = K ((1 - zero / pole) z2 + (zero / pole) z1)``:
    the entries of ``A`` are ``1 / pole`` (a companion form would have ``1 / pole^2`` and be badly scaled
    for the centimetre length scales of the FAWT).
    """
    a = np.array([[-1.0 / pole, 0.0], [1.0 / pole, -1.0 / pole]])
    b = np.array([[1.0 / pole], [0.0]])
    k = sig * math.sqrt(gain_len)
    c = np.array([[k * zero / pole, k * (1.0 - zero / pole)]])
    return a, b, c


def spatial_state_space(params: DrydenParams, rates: bool = False) -> tuple[NDArray, NDArray, NDArray]:
    """``(A, B, C)`` of the spatial-domain Dryden filters; outputs ``[u, v, w]`` (+ ``[p, dw/dxi, dv/dxi]``).

    Noise inputs are ``[n_u, n_v, n_w]`` (+ ``n_p``), each unit-intensity white in distance.
    """
    su, sv, sw = params.sigma
    lu, lv, lw = params.length
    blocks_a: list[NDArray] = []
    blocks_b: list[tuple[int, NDArray]] = []
    outs_c: list[NDArray] = []
    # u: first order
    blocks_a.append(np.array([[-1.0 / lu]]))
    blocks_b.append((0, np.array([[1.0 / lu]])))
    outs_c.append(np.array([[su * math.sqrt(2.0 * lu)]]))
    for sig, length, col in ((sv, lv, 1), (sw, lw, 2)):
        if params.form == "8785c":
            a, b, c = _second_order(sig, length, math.sqrt(3.0) * length, length)
        else:
            a, b, c = _second_order(sig, 2.0 * length, 2.0 * math.sqrt(3.0) * length, 2.0 * length)
        blocks_a.append(a)
        blocks_b.append((col, b))
        outs_c.append(c)
    n_in = 3
    if rates:
        n_in = 4
        span = params.span
        tp = 4.0 * span / math.pi
        gain_p = math.sqrt(math.pi * 0.8) * sw * (math.pi / (4.0 * span)) ** (1.0 / 6.0) * lw ** (-1.0 / 3.0)
        blocks_a.append(np.array([[-1.0 / tp]]))
        blocks_b.append((3, np.array([[1.0 / tp]])))
        outs_c.append(np.array([[gain_p]]))
    n = sum(a.shape[0] for a in blocks_a)
    big_a = scipy.linalg.block_diag(*blocks_a)
    big_b = np.zeros((n, n_in))
    n_out = 6 if rates else 3
    big_c = np.zeros((n_out, n + (2 if rates else 0)))
    idx = 0
    for k, (a, (col, b), c) in enumerate(zip(blocks_a, blocks_b, outs_c, strict=True)):
        m = a.shape[0]
        big_b[idx:idx + m, col:col + 1] = b
        out_row = k if k < 3 else 3
        big_c[out_row, idx:idx + m] = c
        idx += m
    if not rates:
        return big_a, big_b, big_c
    # gradient filters d/dxi low-passed: q = (w - z_q) / tq with z_q' = (w - z_q) / tq (same for r from v)
    tq, tr = 4.0 * params.span / math.pi, 3.0 * params.span / math.pi
    a_ext = np.zeros((n + 2, n + 2))
    a_ext[:n, :n] = big_a
    b_ext = np.zeros((n + 2, n_in))
    b_ext[:n] = big_b
    cw, cv = big_c[2, :n], big_c[1, :n]
    a_ext[n, :n] = cw / tq
    a_ext[n, n] = -1.0 / tq
    a_ext[n + 1, :n] = cv / tr
    a_ext[n + 1, n + 1] = -1.0 / tr
    big_c[4, :n] = cw / tq
    big_c[4, n] = -1.0 / tq
    big_c[5, :n] = cv / tr
    big_c[5, n + 1] = -1.0 / tr
    return a_ext, b_ext, big_c
