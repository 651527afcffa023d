"""Plain-text reports shared by the result objects and the command line: what produced a
result (the model, impact rule and restitution; a record's file, units, step and PGA) and
the derived quantities of a structure, as plain Python values and as lines of text."""

from __future__ import annotations

import pathlib

import numpy as np

from ._records import G_STANDARD

#: the models whose impacts are their landings, not the SDOF impact rule
BODY_MODELS = ("rigid_body", "two_spring_2dof")
#: the units of the derived quantities of a structure (`derived_table`, pushover --json)
DERIVED_UNITS = {"W": "N", "H_c": "m", "R_c": "m", "alpha_c": "rad", "R_e": "m",
                 "alpha_e": "rad", "R_b": "m", "alpha_b": "rad", "delta_0": "m",
                 "theta_crit": "rad", "u_crit": "m", "K1": "N/m", "P_crit": "N",
                 "P_crit2": "N", "u_overturn": "m", "restitution": "-"}


def model_info(model, impact="paper", r=None) -> dict:
    """The model (its name), impact rule and restitution behind a result, for text and
    JSON; the body models impact at their landings (an impact rule does not apply)."""
    impact = "landings" if model in BODY_MODELS else impact
    return {"model": model, "impact": impact, "r": "Eq 3" if r is None else r}


def model_line(info) -> str:
    """`model_info` as one line of text."""
    r = info["r"] if isinstance(info["r"], str) else f"{info['r']:g}"
    if info["impact"] == "landings":
        return f"{info['model']} model, impacts at landings (Eqs 2-3), r {r}"
    return f"{info['model']} model, impact rule {info['impact']}, r {r}"


def record_info(record, scale=1.0) -> dict:
    """What was read from a record (a `Record`, or a one-record `GroundMotion`: no file,
    m/s², its own scale applied): file, units (and where they came from), dt, points,
    duration, PGA and the scale applied, as plain Python (SI units, PGA also in g)."""
    acc, dt = np.asarray(record.accel), float(record.dt)
    pga, g = float(np.max(np.abs(acc))) * float(getattr(record, "scale", 1.0)), G_STANDARD
    return {"file": str(getattr(record, "source", "")),
            "units_in_file": getattr(record, "units_in_file", "m/s2"),
            "units_from": getattr(record, "units_source", None), "dt_s": dt,
            "n_points": int(acc.size), "duration_s": dt * (acc.size - 1),
            "pga_m_s2": pga, "pga_g": pga / g, "scale": float(scale),
            "scaled_pga_g": float(scale) * pga / g}


def record_line(info) -> str:
    """`record_info` as one line of text."""
    src = f" ({info['units_from']})" if info.get("units_from") else ""
    return (
        f"{pathlib.Path(info['file']).name}: units {info['units_in_file']}{src}, "
        f"dt {info['dt_s']:g} s, {info['n_points']} points, {info['duration_s']:g} s, "
        f"PGA {info['pga_g']:.4g} g x scale {info['scale']:g} = {info['scaled_pga_g']:.4g} g"
    )


def derived_table(derived) -> str:
    """The derived quantities of a structure (`RockingStructure.derived()`) as a text
    table (angles also in degrees)."""
    lines = [f"{'quantity':<14}{'value':>14}  unit"]
    for k, unit in DERIVED_UNITS.items():
        extra = f"  ({derived[k + '_deg']:.4f} deg)" if k + "_deg" in derived else ""
        lines.append(f"{k:<14}{derived[k]:>14.6g}  {unit}{extra}")
    return "\n".join(lines)


def status_line(counts) -> str:
    """The runs per status (`SweepResult.status_counts`), those with none left out."""
    return ", ".join(f"{k} {v}" for k, v in counts.items() if v)


def pushover_table(derived, curves) -> str:
    """`derived_table`, then the pushover curves (`rockjax._plotting.pushover_curves`:
    u [m] and the simplified, exact and numerical forces [N]) at 21 points of their
    range."""
    n = len(curves["u"])
    lines = [derived_table(derived), "", f"{'u [m]':>10} {'simplified [N]':>15} "
             f"{'exact [N]':>12} {'numerical [N]':>14}"]
    lines += [f"{curves['u'][i]:10.5f} {curves['simplified'][i]:15.3f} "
              f"{curves['exact'][i]:12.3f} {curves['numerical'][i]:14.3f}"
              for i in sorted({int(round(k * (n - 1) / 20)) for k in range(21)})]
    return "\n".join(lines)
