"""The log-likelihood's gradient by forward sensitivities (stochastic.gradient) against central differences of
the filter itself: two levels, a parameter-dependent read-out and offset, a stiff state (the Lyapunov branch of
the step noise), time-varying and stationary rows; and a fit with it reaches the finite-difference fit's optimum."""

import numpy as np
import pytest

from thermodrift.core.physics.stochastic import gradient, kalman
from thermodrift.core.physics.stochastic.fit import Param, _values, fit
from thermodrift.core.physics.stochastic.sde import Series, System


class TwoLevel:
    name = "two_level"
    parameters = (Param("a", 0.4, 1e-3, 1e3), Param("b", 0.2, 1e-3, 1e3), Param("fast", 30.0, 1e-2, 1e4),
                  Param("g", 0.5, -5.0, 5.0), Param("s1", 0.2, 1e-4, 10.0), Param("s2", 0.1, 1e-4, 10.0),
                  Param("off", 0.3, -5.0, 5.0), Param("r", 0.05, 1e-4, 5.0))

    def system(self, v):
        A = np.array([[[-v["a"], v["b"]], [v["fast"], -v["fast"] - 0.1]],
                      [[-2 * v["a"], v["b"]], [v["fast"], -v["fast"] - 0.3]]])
        B = np.array([[[v["g"], 0.1], [0.0, 0.2]], [[v["g"], 0.3], [0.0, 0.1]]])
        C = np.array([[v["g"], 1.0]])
        D = np.array([[v["off"], 0.0]])
        return System(A, B, C, D, np.array([v["s1"], v["s2"]]), np.array([v["r"]]))


def _data(n=400, seed=1):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.25
    u = np.column_stack([np.ones(n), np.sin(t / 3) + rng.normal(0, 0.1, n)])
    level = (np.arange(n) // 150) % 2
    return Series.of(t, u, np.cumsum(rng.normal(0, 0.05, n)) + 1.0, level)


@pytest.mark.parametrize("transient", [0, 30, 400])
def test_the_gradient_matches_central_differences_of_the_filter(transient):
    model, data = TwoLevel(), _data()
    params = model.parameters
    eta = np.array([p.to_eta(p.value) for p in params])
    lo, hi = np.array([p.eta_bounds for p in params]).T
    at = lambda e: model.system(_values(params, e))  # noqa: E731
    d = gradient.derivatives(at, eta, lo, hi, data, 96)
    ll, g = gradient.run(at(eta), d, data, transient=transient)
    assert ll == kalman.run(at(eta), data, transient=transient).loglik
    rows = gradient.scores(at(eta), d, data, transient=transient)  # the same gradient, row by row
    assert rows.shape == (len(data), len(eta)) and np.allclose(rows.sum(axis=0), g, rtol=1e-8, atol=1e-8)
    h = 1e-5
    for i in range(len(eta)):
        up, dn = eta.copy(), eta.copy()
        up[i] += h
        dn[i] -= h
        fd = (kalman.run(at(up), data, transient=transient).loglik
              - kalman.run(at(dn), data, transient=transient).loglik) / (2 * h)
        assert g[i] == pytest.approx(fd, rel=1e-5, abs=1e-4), params[i].name


def test_a_fit_with_the_gradient_reaches_the_finite_difference_optimum_in_fewer_passes():
    model, data = TwoLevel(), _data(160, seed=4)
    a = fit(model, data, seed=0, starts=1, information=False)
    b = fit(model, data, seed=0, starts=1, information=False, gradient=False)
    assert a.loglik >= b.loglik - 1e-3
    assert a.n_evals < b.n_evals
    assert fit(model, data, seed=0, starts=1, information=False).values == a.values


class OneState:
    name = "one_state"
    parameters = (Param("a", 0.5, 1e-3, 1e2), Param("g", 1.0, -5.0, 5.0), Param("s", 0.1, 1e-4, 10.0),
                  Param("r", 0.05, 1e-4, 5.0))

    def system(self, v):
        return System(np.array([[[-v["a"]]]]), np.array([[[v["a"] * v["g"]]]]), np.array([[1.0]]),
                      np.zeros((1, 1)), np.array([v["s"]]), np.array([v["r"]]))


def test_the_misfit_scale_is_one_where_the_model_fits_and_large_where_it_misses_a_slow_part():
    """tr(H⁻¹J)/k: the scores' long-run variance against the information. Data from the model itself: about 1;
    data with a slow part the model lacks (a second state, hours slower): innovations correlated over hours, J ≫ H."""
    from thermodrift.core.physics.stochastic import simulate
    from thermodrift.core.physics.stochastic.fit import misfit_scale

    n = 600
    rng = np.random.default_rng(3)
    t = np.arange(n) * 0.25
    u = np.repeat(rng.choice([0.0, 1.0, 2.0], n // 40), 40)[:, None]
    model = OneState()
    truth = model.system({"a": 0.5, "g": 1.0, "s": 0.1, "r": 0.05})
    y = simulate(truth, Series.of(t, u, np.zeros((n, 1))), seed=3)
    right = fit(model, Series.of(t, u, y), seed=0, starts=1)
    slow = np.cumsum(u[:, 0] - u[:, 0].mean()) * 0.01  # a slow heat store the model has no state for
    wrong = fit(model, Series.of(t, u, y + slow[:, None]), seed=0, starts=1)
    assert misfit_scale(right) < 1.3
    assert misfit_scale(wrong) > 1.6
