"""Calibration of a thermal network to a recording by re-simulating the whole trajectory (grey-box output error).

Public API (stable; the missing-physics finder builds on it)::

    from thermodrift.core.physics import calibration as cal

    result = cal.calibrate(recording, network=None,        # None: the auto network of the recording
                           free=None,                      # [FreeParameter] or globs over network paths
                           targets=None, hidden_nodes=2,
                           max_evaluations=200, starts=1, seed=0, level=0.95,
                           prior_strength=None)            # None: auto network's prior chosen on a held-out block
    result.rmse_initial, result.rmse     # {channel: RMSE} on every sample (K, µm), start and calibrated
    result.network                       # the calibrated Network (estimates and linear map written in)
    result.estimates                     # [Estimate(name, paths, value, start, low, high, se, at_bound, unit, log)]
    result.linear, result.linear_ci      # offsets, sensitivities µm/K, projected heat W; intervals
    result.stop                          # "tolerance" | "evaluation_cap" | "no_free_parameters"
    result.starts, result.spread         # per-start cost/stop/values; max/min over starts
    result.residuals                     # measured − calibrated (DataFrame, time_s index)
    result.warnings                      # worse temperature channels, starts not kept, capped grid
    result.prior                         # Prior on the nonlinear parameters (strength, how it was chosen) or None
    result.to_dict()                     # calibration.json: rmse_initial and rmse at the top level

    cal.FreeParameter(name, paths=("edges.a-b.G_W_K",), value=2.0, low=0.1, high=50.0, unit="W/K", scale="log")
    cal.auto_network(recording)          # AutoBaseline(network, free, assumptions, channel_nodes, time_constants_s)
    cal.predict(network, scenario)       # open-loop readings and node temperatures
    cal.StateObserver(network, sensors)  # Kalman filter over the network with the measured temperatures
    cal.cv_ridge(A, Y), cal.ridge_solve(A, Y, lam)  # the ridge strength by blocked CV, and the ridge fit

A mechanism adds its own parameters by passing ``free=[*auto.free, *mechanism_parameters]`` with a network that
contains its element: :meth:`Mechanism.declare <thermodrift.core.physics.mechanisms.Mechanism.declare>` returns them
as :class:`FreeParameter` s, the one free-parameter type (``scale="projected"`` ones are solved linearly and are not
searched: leave them out). Modules by job: :mod:`.free` (free parameters), :mod:`.auto` (the auto network and what
it assumes), :mod:`.objective` (re-simulation, variable projection, ridge sensitivities, the fit grid),
:mod:`.uncertainty` (intervals, identifiability), :mod:`.prior` (the auto network's prior), :mod:`.fit` (the search
and the result), :mod:`.prediction` (open loop and the state observer).

Determinism: the search (``scipy.optimize.least_squares``, trust-region reflective, bounds) stops on its
tolerances or on ``max_evaluations`` iterations per start, never on wall-clock time; extra starts are jittered
from ``seed``. The same inputs give the same result on the same kind of CPU, however loaded.
"""

from thermodrift.core.physics.calibration.auto import (AUTO_AMBIENT_DEGC, AUTO_ASSUMPTIONS, AUTO_CAPACITY_J_K,
                                                       AutoBaseline, auto_network, step_response_start)
from thermodrift.core.physics.calibration.fit import CalibrationResult, calibrate
from thermodrift.core.physics.calibration.free import FreeParameter, default_free, free_from_paths
from thermodrift.core.physics.calibration.objective import cv_ridge, fit_rows, noise_sigma, ridge_solve
from thermodrift.core.physics.calibration.prediction import StateObserver, predict
from thermodrift.core.physics.calibration.prior import STRENGTH_GRID, Prior
from thermodrift.core.physics.calibration.uncertainty import NULL_TOLERANCE, UNIDENTIFIABLE_RATIO, Estimate

__all__ = [
    "AUTO_AMBIENT_DEGC", "AUTO_ASSUMPTIONS", "AUTO_CAPACITY_J_K", "AutoBaseline", "CalibrationResult", "Estimate",
    "FreeParameter", "NULL_TOLERANCE", "Prior", "STRENGTH_GRID", "StateObserver", "UNIDENTIFIABLE_RATIO",
    "auto_network", "calibrate", "cv_ridge", "default_free", "fit_rows", "free_from_paths", "noise_sigma", "predict",
    "ridge_solve", "step_response_start",
]
