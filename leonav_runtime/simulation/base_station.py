"""The simulated base station (`[base]`, ephemeris method 3): a receiver at rest at a known
position that sees the same true orbits as the rover.

Two kinds of corrections (`[base] corrections`):
- "measurement": what the orbit error does to each observable at the base (plus the base's
  noise), minus each epoch's mean; the rover subtracts it. It decays with the baseline: the
  orbit error's effect depends on the geometry.
- "orbit": the base estimates each satellite's radial / along-track / cross-track offset from
  its own measurements (base/orbit_fit.py, causal, served every `serve_interval_s`) and the
  rover moves its element-orbit satellite states by the latest one served; its R grows by what
  the estimate's covariance does to each measurement. An orbit offset is the same at every
  receiver, so nothing decays with the baseline but the estimate's error.
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.base.orbit_fit import OrbitFit, fit_orbit_offsets
from leonav_runtime.core import model
from leonav_runtime.inputs.consider import records_per_satellite
from leonav_runtime.simulation.orbit_truth import (base_state, ephemeris_delta, ephemeris_sigma, moved_aux,
                                                   moved_states, sigma_rac)
from leonav_runtime.simulation.sensor_errors import own_stream


def base_corrections(setup, nav, rng: np.random.Generator, part: list, errors: dict) -> np.ndarray:
    """A base station's corrections (measurement unit) for one part [kind_name, rows, z, sigma]:
    what the orbit error does to the same observable at the base's known position (`[base]`
    offset from the site, at rest), plus the base's own noise (the part's sigma, its own
    stream), minus its mean over each epoch's satellites (the base's LO and clock are common to
    an epoch; the rover's own states take up what that removes). The rover subtracts them and
    adds their variance to R (simulation: corrections of the rover's epoch, age 0)."""
    kind_name, rows = part[0], part[1]
    delta = ephemeris_delta(setup, nav, kind_name, rows, errors, x_at=base_state(setup))
    sigma = np.broadcast_to(np.asarray(part[3], float), delta.shape)
    corr = delta + sigma * own_stream(rng, f"base:{kind_name}").standard_normal(delta.size)
    t = setup.series[kind_name].t_s[rows]
    _, index = np.unique(t, return_inverse=True)
    mean = np.bincount(index, corr) / np.bincount(index)
    return corr - mean[index]


def _starlink(parts: list) -> list:
    return [p for p in parts if model.observable(p[0]).constellation == "starlink"]


def _orbit_rows(setup, nav, part: list, x: np.ndarray, d_at: np.ndarray, rows: np.ndarray | None = None,
                step_m: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The model's change (n,) at a part's rows (`rows`: positions among them, default all) for a
    receiver at x (NX,) or (n, NX) with the satellites moved by d_at (n, 3) m, and its derivative
    (n, 3) per m of radial, along, cross offset: central differences of the generated h over
    moved_aux, so it is the derivative of what the offsets do (an along-track offset moves a
    time difference's both ends along the orbit), not of one aux column at a time."""
    sel = slice(None) if rows is None else rows
    kind_name, part_rows = part[0], part[1][sel]
    n = part_rows.size
    steps = np.concatenate([np.zeros((1, 3)), step_m * np.eye(3), -step_m * np.eye(3)])   # one call for all seven
    d = (d_at[None, :, :] + steps[:, None, :]).reshape(-1, 3)
    aux = np.concatenate([setup.series[kind_name].aux[part_rows], moved_aux(setup, kind_name, np.tile(part_rows, 7), d,
                                                                            None, nav.layout)])
    x_rows = np.broadcast_to(x, (n, x.shape[-1])) if x.ndim == 1 else x
    h = nav.h_many(kind_name, np.tile(x_rows, (8, 1)), aux, params=setup.params, jacobian=False)[0].reshape(8, n)
    return h[1] - h[0], ((h[2:5] - h[5:8]) / (2.0 * step_m)).T


def orbit_fit(setup, nav, rng: np.random.Generator, parts: list, errors: dict) -> OrbitFit:
    """The simulated base's served orbit corrections from its own measurements of the rover's
    undifferenced Starlink observables (`parts` [kind_name, rows, z, sigma], the rover's rows and
    tone sigmas): the true orbits seen from the base, its own noise and receiver states (drawn
    from their priors, own streams), fitted by base/orbit_fit.py."""
    x_base = base_state(setup)
    cols = np.concatenate([np.arange(b.error_offset, b.error_offset + b.error_size) for b in model.measurement_blocks()])
    sig_common = np.sqrt(np.diag(setup.P0)[cols])
    cols, sig_common = cols[sig_common > 0], sig_common[sig_common > 0]
    c_true = sig_common * own_stream(rng, "base:receiver").standard_normal(cols.size)
    pieces = []
    for j, part in enumerate(parts):
        kind_name, rows = part[0], part[1]
        s = setup.series[kind_name]
        _, H = nav.h_many(kind_name, x_base, s.aux[rows], params=setup.params)
        sigma = np.broadcast_to(np.asarray(part[3], float), rows.shape)
        noise = sigma * own_stream(rng, f"base:{kind_name}").standard_normal(rows.size)
        residual = ephemeris_delta(setup, nav, kind_name, rows, errors, x_at=x_base) + H[:, cols] @ c_true + noise
        t = s.t_s[rows]
        group = j * (1 << 32) + np.rint(t * 1e3).astype(np.int64)    # an epoch of one kind (ms tags)
        pieces.append((s.sat_id[rows], t, group, residual, sigma, H[:, cols], np.full(rows.size, j), np.arange(rows.size)))
    *cat, part_of, position = (np.concatenate(c) for c in zip(*pieces))

    def linearize(index: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        dh, A = np.empty(index.size), np.empty((index.size, 3))
        for j, part in enumerate(parts):
            here = part_of[index] == j
            if here.any():
                dh[here], A[here] = _orbit_rows(setup, nav, part, x_base, d[here], position[index[here]])
        return dh, A
    serve = setup.scn.realism["base"]["serve_interval_s"]
    t_serve = np.arange(serve, setup.scn.duration_s + 0.5 * serve, serve)
    return fit_orbit_offsets(*cat, linearize=linearize,
                             prior_sigma_rac_m=sigma_rac(setup.scn.realism["ephemeris"], "starlink"),
                             prior_sigma_common=sig_common, t_serve=t_serve)


def _orbit_variance(setup, nav, part: list, cov: np.ndarray, d_hat: np.ndarray) -> np.ndarray:
    """(n,) what a served offset's covariance (n, 3, 3) m^2 does to each row's variance, linear
    about the served offsets d_hat (n, 3) m at the true receiver state (as inflate-r's one-sigma
    moves)."""
    k = np.rint(setup.series[part[0]].t_s[part[1]] * setup.scn.imu_rate_hz).astype(int)
    _, A = _orbit_rows(setup, nav, part, setup.x_true[k], d_hat)
    return np.einsum("ni,nij,nj->n", A, cov, A)


def orbit_corrected(scn, kind_name: str) -> bool:
    """Whether the scenario's base corrects this observable kind in the orbit domain (an
    undifferenced Starlink observable, `[base] corrections = \"orbit\"`)."""
    o, base = model.observable(kind_name), scn.realism.get("base", {})
    return bool(base.get("enabled")) and base.get("corrections") == "orbit" and o.constellation == "starlink" \
        and not o.reads_ref


def apply(setup, nav, rng: np.random.Generator, parts: list, errors: dict) -> None:
    """The base's corrections on one trial's parts, in place (module doc). With `[ephemeris_error]
    compensate` the filter's R grows by what they leave: inflate-r, white; consider (orbit
    corrections), the served covariance's term times the satellite's records within
    `consider_correlation_s`, as the road's consider term treats an error its records share
    (inputs/consider.py); measurement corrections under consider keep the road's term."""
    eph = setup.scn.realism["ephemeris"]
    inflate, consider = eph["compensate"] == "inflate-r", eph["compensate"] == "consider"
    starlink = _starlink(parts)
    by_orbit = [p for p in starlink if orbit_corrected(setup.scn, p[0])]
    x_base = base_state(setup)
    for part in (p for p in starlink if not orbit_corrected(setup.scn, p[0])):   # the effect at the base, subtracted
        left = ephemeris_sigma(setup, nav, part[0], part[1], x_base) if inflate else 0.0
        part[2] = part[2] - base_corrections(setup, nav, rng, part, errors)
        part[3] = np.sqrt(2.0 * np.asarray(part[3], float) ** 2 + left**2)   # the base's noise beside the rover's
    if not by_orbit:
        return
    fit = orbit_fit(setup, nav, rng, by_orbit, errors)
    for part in by_orbit:
        s, rows = setup.series[part[0]], part[1]
        d_hat, cov = fit.at(s.sat_id[rows], s.t_s[rows])
        if inflate or consider:
            m = records_per_satellite(s.sat_id[rows], s.t_s[rows], eph["consider_correlation_s"] if consider else 0.0)
            part[3] = np.sqrt(np.asarray(part[3], float) ** 2 + m * _orbit_variance(setup, nav, part, cov, d_hat))
        part[4:] = [moved_states(s, rows, d_hat)]
