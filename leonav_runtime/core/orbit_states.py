"""Ephemeris method 1: each tracked satellite's orbit offset as states beside the filter's.

`OrbitStates` holds what `leonav_run_orbit` (csrc/leonav_orbit_states.h, where the algebra is
documented) carries beside the generated filter's x and P: per slot a satellite's radial,
along-track and cross-track offset from its ephemeris (m), their covariance with the navigation
state and with each other. `EKF.run(recs, orbit=OrbitStates(...))` runs it. The kinds whose
records read their satellite's offsets are the registry's undifferenced Starlink satellite
observables (`offset_kinds`), the ones a base station corrects in the orbit domain.
"""
from __future__ import annotations

import ctypes

import numpy as np

from leonav_runtime.core import model
from leonav_runtime.core.compiled import OrbitStatesC

MAX_SLOTS = 256   # LEONAV_ORBIT_MAX_SLOTS
_dp = ctypes.POINTER(ctypes.c_double)


def offset_observables() -> set[str]:
    """Observables (suffixes) whose satellites' offsets are states: undifferenced Starlink
    satellite observables (a differenced one reads a reference satellite too)."""
    return {o.suffix for o in model.OBSERVABLES
            if o.table == "satellite" and o.constellation == "starlink" and not o.reads_ref}


def offset_kinds() -> set[int]:
    """Observable ids of `offset_observables`."""
    names = offset_observables()
    return {int(o.kind) for o in model.OBSERVABLES if o.suffix in names}


class OrbitStates:
    """The orbit-offset states of one run: `n_slots` satellites at a time, each joining with
    prior sigmas `prior_sigma_rac_m` (radial, along, cross; m) and walking with PSD `q_rw_m2_s`
    (m^2/s per axis; 0: random constants); a slot is reused once its satellite has had no
    record for `free_after_s` (s). After a run: `satellites()` the offsets in the slots."""

    def __init__(self, ndx: int, n_meas: int, n_slots: int, prior_sigma_rac_m, q_rw_m2_s=(0.0, 0.0, 0.0),
                 free_after_s: float = 30.0, kinds: set[int] | None = None) -> None:
        if not 1 <= int(n_slots) <= MAX_SLOTS:
            raise ValueError(f"orbit states: n_slots {n_slots}; expected 1..{MAX_SLOTS}")
        sig = np.asarray(prior_sigma_rac_m, dtype=float)
        q = np.asarray(q_rw_m2_s, dtype=float)
        if sig.shape != (3,) or q.shape != (3,) or not (np.all(sig > 0) and np.all(np.isfinite(sig))
                                                        and np.all(q >= 0) and np.all(np.isfinite(q))):
            raise ValueError(f"orbit states: prior sigmas {sig.tolist()} m (3 > 0) and random walk {q.tolist()} "
                             "m^2/s (3 >= 0) expected")
        if not (free_after_s > 0 and np.isfinite(free_after_s)):
            raise ValueError(f"orbit states: free_after_s {free_after_s!r}; expected > 0 s")
        m = 3 * int(n_slots)
        self.kind_offsets = np.zeros(n_meas, np.uint8)
        self.kind_offsets[sorted(offset_kinds() if kinds is None else kinds)] = 1
        self.slot_sat = np.full(n_slots, -1, np.int32)
        self.slot_last_t = np.zeros(n_slots)
        self.offset = np.zeros(m)
        self.P_no = np.zeros((m, ndx))          # column-major NDX x 3K: row c is column c
        self.P_oo = np.zeros((m, m))            # the C keeps its lower triangle: see `offset_covariance`
        self.c = OrbitStatesC(int(n_slots), (ctypes.c_double * 3)(*(sig**2)), (ctypes.c_double * 3)(*q),
                              float(free_after_s), self.kind_offsets.ctypes.data_as(ctypes.POINTER(ctypes.c_uint8)),
                              self.slot_sat.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)),
                              self.slot_last_t.ctypes.data_as(_dp), self.offset.ctypes.data_as(_dp),
                              self.P_no.ctypes.data_as(_dp), self.P_oo.ctypes.data_as(_dp), 0, 0, 0)

    def offset_covariance(self) -> np.ndarray:
        """(3 n_slots, 3 n_slots) covariance of the offsets (m^2), slot j in rows 3j..3j+2."""
        lower = np.triu(self.P_oo).T      # column-major lower triangle = this array's upper one
        return lower + np.tril(lower, -1).T

    @property
    def counts(self) -> dict[str, int]:
        """Slots taken, of them reused from a satellite gone, records that found no slot."""
        return {"slots_taken": int(self.c.n_taken), "slots_reused": int(self.c.n_reused),
                "no_slot": int(self.c.n_no_slot)}

    def summary(self) -> dict:
        """counts, and per satellite in a slot its offsets and their sigmas (m), JSON-ready."""
        return {**self.counts, "satellites": {str(s): {"offset_rac_m": o.tolist(), "sigma_rac_m": g.tolist()}
                                              for s, (o, g) in self.satellites().items()}}

    def satellites(self) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """{satellite id: (offset radial/along/cross m, its sigmas m)} of the satellites in the slots."""
        out = {}
        for j, sat in enumerate(self.slot_sat.tolist()):
            if sat >= 0:
                c = slice(3 * j, 3 * j + 3)
                out[sat] = (self.offset[c].copy(), np.sqrt(np.diag(self.P_oo[c, c])))
        return out


def move_aux(lib, aux: np.ndarray, d_rac: np.ndarray) -> np.ndarray:
    """Rows of aux (n, NAUX) with their satellite moved by d_rac (n, 3) m, by the C filter's move."""
    aux = np.ascontiguousarray(aux, dtype=np.float64)
    d = np.ascontiguousarray(np.broadcast_to(d_rac, (aux.shape[0], 3)), dtype=np.float64)
    out = np.empty_like(aux)
    for k in range(aux.shape[0]):
        lib.leonav_orbit_move_aux(aux[k].ctypes.data_as(_dp), d[k].ctypes.data_as(_dp), out[k].ctypes.data_as(_dp))
    return out
