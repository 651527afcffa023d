"""rockjax against an independent numpy/scipy implementation of Eqs 1–3, 13, 20.

The reference below re-derives every quantity from the structure's raw fields (it does not
use rockjax's derived properties, restoring forces or record reader) and integrates Eq. 1
with `scipy.integrate.solve_ivp` (DOP853, rtol=1e-12, atol=1e-14) in a Python loop over
segments:

- each impact (u crosses 0) is a terminal event; the run restarts from u = 0 with
  v <- sqrt(r) v (Eq. 2, same sign);
- the simplified k(u) jumps at |u| = u_crit (P_crit -> P_crit2), so crossing u_crit is a
  terminal event as well and each piece integrates one smooth branch;
- the record is linear between samples, so the integration is split at every sample time
  (each piece has a smooth, linear forcing);
- the peak |u| is taken where v = 0 (a non-terminal event) and at the ends of every piece.

The reference is also used by `benchmarks/single_run.py` (with looser tolerances as the
scipy baseline).
"""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from scipy.integrate import solve_ivp

G_STANDARD = 9.80665  # m/s² per g, for records in units of g


# --------------------------------------------------------------------------------------
# Independent reference implementation
# --------------------------------------------------------------------------------------


def reference_params(fields: dict) -> dict:
    """Derived quantities of the paper (SI) from the raw structure fields."""
    m_e, m_b = fields["m_e"], fields["m_b"]
    H_e, H_b, B = fields["H_e"], fields["H_b"], fields["B"]
    I_eg, I_bg, k_f, g = fields["I_eg"], fields["I_bg"], fields["k_f"], fields["g"]
    M = m_e + m_b
    W = M * g
    H_c = (m_e * H_e + m_b * H_b) / M
    R_c = math.hypot(B, H_c)
    alpha_c = math.atan(B / H_c)
    R_e = math.hypot(B, H_e)
    alpha_e = math.atan(B / H_e)
    theta_crit = W / (2 * k_f * B)
    u_crit = W * H_e / (2 * k_f * B)
    K1 = (2 * k_f * B**2 - W * H_c) / H_e**2
    P_crit2 = W * R_c * math.sin(alpha_c - theta_crit) / (R_e * math.cos(alpha_e - theta_crit))
    u_overturn = R_e * (math.sin(alpha_e) + math.sin(alpha_c - alpha_e))
    num = m_e * (H_e**2 - B**2) + I_eg + m_b * (H_b**2 - B**2) + I_bg
    den = m_e * (H_e**2 + B**2) + I_eg + m_b * (H_b**2 + B**2) + I_bg
    r = (num / den) ** 2
    return dict(M=M, W=W, u_crit=u_crit, K1=K1, P_crit2=P_crit2, u_overturn=u_overturn, r=r)


def k_simplified(p: dict, u):
    """The simplified restoring force k(u) [N] (Eq. 13 below u_crit, Eq. 20 above)."""
    u = np.asarray(u, dtype=float)
    a = np.abs(u)
    post = np.sign(u) * p["P_crit2"] * (a - p["u_overturn"]) / (p["u_crit"] - p["u_overturn"])
    return np.where(a <= p["u_crit"], p["K1"] * u, post)


def read_at2(path) -> tuple[float, np.ndarray]:
    """A PEER AT2 file: 4 header lines (NPTS, DT on the 4th), values in g -> (dt, m/s²)."""
    lines = pathlib.Path(path).read_text().splitlines()
    header = lines[3].upper().replace(",", " ")
    tokens = header.replace("=", " ").split()
    npts = int(tokens[tokens.index("NPTS") + 1])
    dt = float(tokens[tokens.index("DT") + 1])
    vals = np.array([float(x) for line in lines[4:] for x in line.split()])
    assert vals.size == npts, (vals.size, npts)
    return dt, vals * G_STANDARD


class ReferenceResult:
    def __init__(self, pieces, impacts, peak_u, status, t_end):
        self._starts = np.array([pc[0] for pc in pieces])
        self._pieces = pieces
        self.impacts = np.asarray(impacts)
        self.n_impacts = len(impacts)
        self.peak_u = peak_u
        self.status = status
        self.t_end = t_end
        self.n_pieces = len(pieces)

    def u_at(self, ts):
        """u on `ts` from the dense output of the piece that covers each time."""
        ts = np.asarray(ts, dtype=float)
        out = np.empty_like(ts)
        idx = np.clip(np.searchsorted(self._starts, ts, side="right") - 1, 0, None)
        for j in np.unique(idx):
            sel = idx == j
            ta, tb, interp, y_end = self._pieces[j]
            tt = ts[sel]
            inside = tt <= tb
            vals = np.empty(tt.shape)
            if np.any(inside):
                vals[inside] = interp(tt[inside])[0] if interp is not None else y_end[0]
            vals[~inside] = y_end[0]  # after the run stopped: hold the last state
            out[sel] = vals
        return out


def reference_simulate(
    fields: dict,
    t1: float,
    *,
    u0: float = 0.0,
    v0: float = 0.0,
    dt: float | None = None,
    accel=None,
    scale: float = 1.0,
    r: float | None = None,
    method: str = "DOP853",
    rtol: float = 1e-12,
    atol: float = 1e-14,
    dense: bool = True,
    split: bool = True,
) -> ReferenceResult:
    """Eq. 1 with impacts at u = 0 (Eq. 2), simplified k(u), by solve_ivp in segments.

    With `split` (default) every record sample starts a new segment, so that no step
    straddles a kink of the interpolated forcing; `split=False` lets solve_ivp step over
    them (cheaper, less accurate: the speed/accuracy curve of a plain scipy user).
    """
    p = reference_params(fields)
    M, u_crit, u_ot, K1 = p["M"], p["u_crit"], p["u_overturn"], p["K1"]
    slope2 = p["P_crit2"] / (u_crit - u_ot)  # post-uplift stiffness (negative)
    sqrt_r = math.sqrt(p["r"] if r is None else r)

    # Times where the forcing has kinks: every record sample, and its end.
    if accel is not None:
        accel = np.asarray(accel, dtype=float) * scale
        n = accel.size
        knots = dt * np.arange(n)
        knots = knots[(knots > 0) & (knots < t1)]
        first_nz = accel[np.argmax(accel != 0)]
        first_dir = -np.sign(first_nz) if first_nz != 0 else 1.0
    else:
        n = 0
        knots = np.array([])
        first_dir = 1.0
    if not split:
        knots = np.array([])
    knots = np.concatenate([[0.0], knots, [t1]])

    def forcing_coeffs(ta):
        """a_g(t) = c0 + c1 t on the piece starting at ta (linear between samples)."""
        if accel is None or not split:
            return 0.0, 0.0
        i = int(math.floor(ta / dt + 1e-9))
        if i >= n - 1:
            return 0.0, 0.0
        a0, a1 = accel[i], accel[i + 1]
        c1 = (a1 - a0) / dt
        return a0 - c1 * i * dt, c1

    # Discrete state: side of u (+1/-1) and branch (0: springs, 1: rocking).
    u, v = float(u0), float(v0)
    side = np.sign(u) if u != 0 else (np.sign(v) if v != 0 else first_dir)
    branch = 1 if abs(u) > u_crit else 0
    E0 = 0.5 * M * v**2 + abs(u) * abs(float(k_simplified(p, u)))
    free = accel is None

    t = 0.0
    k = 1  # index of the next knot
    impacts: list[float] = []
    peak = abs(u)
    pieces = []
    status = "completed"
    while t < t1:
        tb = knots[k]
        c0, c1 = forcing_coeffs(t)

        if split or accel is None:

            def ag(tt, c0=c0, c1=c1):
                return c0 + c1 * tt

        else:

            def ag(tt):
                x = tt / dt
                return float(np.interp(x, np.arange(n), accel)) if x <= n - 1 else 0.0

        if branch == 0:

            def fun(tt, y):
                return [y[1], -K1 * y[0] / M - ag(tt)]

        else:

            def fun(tt, y, side=side):
                return [y[1], -side * slope2 * (side * y[0] - u_ot) / M - ag(tt)]

        def ev_impact(tt, y):
            return y[0]

        ev_impact.terminal = True
        ev_impact.direction = -side

        def ev_crit(tt, y, side=side):
            return side * y[0] - u_crit

        ev_crit.terminal = True
        ev_crit.direction = 1 if branch == 0 else -1

        def ev_overturn(tt, y, side=side):
            return side * y[0] - u_ot

        ev_overturn.terminal = True
        ev_overturn.direction = 1

        def ev_peak(tt, y):
            return y[1]

        ev_peak.terminal = False
        ev_peak.direction = 0

        sol = solve_ivp(
            fun,
            (t, tb),
            [u, v],
            method=method,
            rtol=rtol,
            atol=atol,
            events=[ev_impact, ev_crit, ev_overturn, ev_peak],
            dense_output=dense,
        )
        if sol.status < 0:
            status = "solver_failure"
            break
        t_end = float(sol.t[-1])
        y_end = sol.y[:, -1].copy()
        pieces.append((t, t_end, sol.sol, y_end))
        if sol.y_events[3].size:
            peak = max(peak, float(np.max(np.abs(sol.y_events[3][:, 0]))))
        peak = max(peak, abs(float(y_end[0])))
        u, v = float(y_end[0]), float(y_end[1])
        t = t_end
        if sol.status == 1:  # a terminal event
            if sol.t_events[0].size:  # impact: restart at u = 0 with sqrt(r) v, Eq. 2
                impacts.append(t)
                u = 0.0
                v = sqrt_r * v
                side = np.sign(v) if v != 0 else -side
                branch = 0
                if free and 0.5 * M * v**2 <= 1e-14 * E0:  # at rest
                    v = 0.0
                    pieces.append((t, t, None, np.array([0.0, 0.0])))
                    break
            elif sol.t_events[2].size:
                status = "overturned"
                peak = max(peak, u_ot)
                break
            elif sol.t_events[1].size:
                branch = 1 - branch
        else:
            k += 1
    return ReferenceResult(pieces, impacts, min(peak, u_ot), status, t)


# --------------------------------------------------------------------------------------
# Tests
# --------------------------------------------------------------------------------------

FREE_U0 = 0.10
FREE_T1 = 4.0
EQ_T1 = 40.0


def _fields(structure) -> dict:
    return {k: float(v) for k, v in structure.to_dict().items()}


def _record_path(ground_motions_dir) -> pathlib.Path:
    path = pathlib.Path(ground_motions_dir) / "IELC180.AT2"
    if not path.is_file():
        pytest.skip(f"{path} not found")
    return path


@pytest.fixture(scope="module")
def free_runs(column):
    import rockjax

    ts = np.linspace(0.0, FREE_T1, 2001)
    res = rockjax.simulate(column, rockjax.FreeVibration(FREE_U0), FREE_T1, ts=ts)
    ref = reference_simulate(_fields(column), FREE_T1, u0=FREE_U0)
    return ts, res, ref


@pytest.fixture(scope="module")
def synthetic_runs(column, synthetic_record):
    """The Table 1 column under the generated test record (conftest.SYNTHETIC_MOTION,
    El Centro's length, step and PGA) for 40 s: rockjax (default method) and scipy."""
    import rockjax

    dt, accel = float(synthetic_record.dt), np.asarray(synthetic_record.accel, float)
    ts = np.arange(int(round(EQ_T1 / dt)) + 1) * dt
    res = rockjax.simulate(column, rockjax.GroundMotion(dt=dt, accel=accel), EQ_T1, ts=ts)
    ref = reference_simulate(_fields(column), EQ_T1, dt=dt, accel=accel)
    return ts, res, ref


@pytest.fixture(scope="module")
def elcentro_runs(column, ground_motions_dir):
    import rockjax

    path = _record_path(ground_motions_dir)
    gm = rockjax.GroundMotion.from_file(path, units="g")
    res = rockjax.simulate(column, gm, EQ_T1)
    dt, accel = read_at2(path)
    ref = reference_simulate(_fields(column), EQ_T1, dt=dt, accel=accel)
    return res, ref


def test_reference_parameters(column):
    p = reference_params(_fields(column))
    assert p["r"] == pytest.approx(0.73544, abs=5e-5)
    assert float(column.restitution) == pytest.approx(p["r"], rel=1e-12)
    assert float(column.u_crit) == pytest.approx(p["u_crit"], rel=1e-12)
    assert float(column.K1) == pytest.approx(p["K1"], rel=1e-12)
    assert float(column.P_crit2) == pytest.approx(p["P_crit2"], rel=1e-12)
    assert float(column.u_overturn) == pytest.approx(p["u_overturn"], rel=1e-12)


def test_free_vibration_matches_scipy(free_runs):
    ts, res, ref = free_runs
    assert res.status_name == "completed", res.status_name
    u_jax = np.asarray(res.u)
    u_ref = ref.u_at(ts)
    err = float(np.max(np.abs(u_jax - u_ref)))
    n_jax, n_ref = int(res.n_impacts), ref.n_impacts
    assert n_jax == n_ref, f"impact count: rockjax {n_jax}, scipy {n_ref}"
    dt_imp = float(np.max(np.abs(res.impacts - ref.impacts))) if n_ref else 0.0
    peak_rel = abs(float(res.peak_u) - ref.peak_u) / ref.peak_u
    msg = (
        f"free vibration u0={FREE_U0}: max|du|={err:.3e} m, impacts {n_jax}/{n_ref}, "
        f"max|dt_impact|={dt_imp:.3e} s, peak rel err={peak_rel:.3e}"
    )
    print(msg)
    assert err <= 1e-5, msg
    assert dt_imp <= 1e-6, msg
    assert peak_rel <= 1e-6, msg


def _compare(res, ref, title):
    """(message, impact counts equal, max |impact time difference| [s], peak rel. error)."""
    n_jax, n_ref = int(res.n_impacts), ref.n_impacts
    peak_rel = abs(float(res.peak_u) - ref.peak_u) / ref.peak_u
    dt_imp = np.inf
    if n_jax == n_ref:
        dt_imp = float(np.max(np.abs(res.impacts - ref.impacts))) if n_ref else 0.0
    msg = (f"{title}: peak u rockjax {float(res.peak_u):.9f} m, scipy {ref.peak_u:.9f} m "
           f"(rel err {peak_rel:.3e}), impacts {n_jax}/{n_ref}, max|dt_impact|={dt_imp:.3e} s")
    print(msg)
    return msg, n_jax == n_ref, dt_imp, peak_rel


def test_synthetic_record_matches_scipy(synthetic_runs):
    """Many impacts (over 200 in 40 s) at El Centro's intensity: the same impacts to
    1e-6 s, the same history and peak."""
    ts, res, ref = synthetic_runs
    assert res.status_name == ref.status == "completed", (res.status_name, ref.status)
    msg, same_n, dt_imp, peak_rel = _compare(res, ref, "synthetic record x1.0")
    assert same_n and ref.n_impacts > 200, msg
    assert dt_imp <= 1e-6, msg
    assert peak_rel <= 1e-6, msg
    err = float(np.max(np.abs(np.asarray(res.u) - ref.u_at(ts))))
    assert err <= 1e-5 * ref.peak_u, f"{msg}, max|du|={err:.3e} m"


def test_synthetic_record_overturning_time_matches_scipy(column, synthetic_record):
    # The synthetic record scaled by 2 overturns the Table 1 column after some 20 impacts
    # (scale 1.5 does not, see test_extremes).
    import rockjax

    dt, accel = float(synthetic_record.dt), np.asarray(synthetic_record.accel, float)
    res = rockjax.simulate(column, rockjax.GroundMotion(dt=dt, accel=accel, scale=2.0), 10.0)
    ref = reference_simulate(_fields(column), 10.0, dt=dt, accel=accel, scale=2.0)
    assert ref.status == "overturned" and res.status_name == "overturned"
    assert np.all(np.isfinite(np.asarray(res.u))) and np.all(np.isfinite(np.asarray(res.v)))
    assert float(res.t_overturn) == pytest.approx(ref.t_end, abs=1e-6), (
        float(res.t_overturn), ref.t_end)
    assert int(res.n_impacts) == ref.n_impacts > 10
    np.testing.assert_allclose(res.impacts, ref.impacts, rtol=0, atol=1e-6)
    assert float(res.peak_u) == pytest.approx(float(column.u_overturn), rel=1e-12)


def test_elcentro_matches_scipy(elcentro_runs):
    """The paper's Fig. 10 case on the real record (skips without the shared folder):
    El Centro 1940 NS x1.0, 243 impacts, peak 102.58 mm, as the scipy reference finds."""
    res, ref = elcentro_runs
    assert res.status_name == ref.status == "completed", (res.status_name, ref.status)
    msg, same_n, dt_imp, peak_rel = _compare(res, ref, "El Centro IELC180 x1.0")
    assert same_n and ref.n_impacts == 243, msg
    assert peak_rel <= 1e-4, msg
    assert ref.peak_u == pytest.approx(0.10258, abs=5e-6), msg
