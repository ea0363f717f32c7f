"""The stochastic grey-box engine: exact discretisation, the Kalman likelihood against the dense Gaussian one,
ML recovery with intervals, unidentifiable parameters named, k-step predictions and whiteness."""

import math

import numpy as np
import pytest
from scipy.integrate import quad_vec
from scipy.linalg import expm
from scipy.stats import multivariate_normal

from thermodrift.core.physics import stochastic as sto
from thermodrift.core.physics.stochastic import kalman, whiteness
from thermodrift.core.physics.stochastic.fit import Param, loglik
from thermodrift.core.physics.stochastic.rc import RCNetwork
from thermodrift.core.physics.stochastic.sde import System

A = np.array([[-0.5, 0.3], [0.2, -0.1]])
B = np.array([[0.4, 0.0], [0.0, 0.1]])


def two_state(sigma=(0.3, 0.1), r=0.05) -> sto.System:
    return sto.System(A[None], B[None], np.array([[1.0, 0.0]]), np.zeros((1, 2)), np.array(sigma), np.array([r]))


def test_discretisation_is_exact_van_loan_against_quadrature():
    s = two_state()
    Phi, Gam, Q = s.discrete(0, 0.7)
    assert np.allclose(Phi, expm(A * 0.7), atol=1e-12)
    assert np.allclose(Gam, quad_vec(lambda t: expm(A * t) @ B, 0, 0.7)[0], atol=1e-10)
    Sig = np.diag(s.sigma ** 2)
    ref = quad_vec(lambda t: expm(A * t) @ Sig @ expm(A.T * t), 0, 0.7)[0]
    assert np.allclose(Q, ref, atol=1e-10)


def test_filter_likelihood_equals_the_dense_gaussian_likelihood():
    """With an exact filter (no stationary switch) the innovations likelihood is the joint Gaussian density of
    the outputs, built here from the discrete steps without any filter."""
    s, rng = two_state(), np.random.default_rng(3)
    n, dt = 30, 0.5
    t = np.arange(n) * dt
    u = rng.normal(size=(n, 2))
    data = sto.Series.of(t, u, rng.normal(size=n))
    x0 = np.array([0.3, -0.2])
    Phi, Gam, Q = s.discrete(0, dt)
    mean, cov = [], []
    m, P = x0, np.eye(2)
    Xs = [(m, P)]
    for k in range(1, n):
        m, P = Phi @ m + Gam @ u[k - 1], Phi @ P @ Phi.T + Q
        Xs.append((m, P))
    C = s.C[0]
    # cov(x_j, x_k) for j ≤ k is Φ^(k−j) P_j
    Sigma = np.empty((n, n))
    for j in range(n):
        for k in range(j, n):
            Sigma[j, k] = Sigma[k, j] = C @ np.linalg.matrix_power(Phi, k - j) @ Xs[j][1] @ C
    Sigma += np.eye(n) * s.r[0] ** 2
    mean = np.array([C @ x for x, _ in Xs])
    ref = multivariate_normal(mean, Sigma).logpdf(data.y[:, 0])
    assert kalman.run(s, data, x0=x0, transient=n, tol=0).loglik == pytest.approx(ref, abs=1e-8)
    # the stationary switch changes it little once the covariance has settled
    assert kalman.run(s, data, x0=x0, transient=10).loglik == pytest.approx(ref, abs=0.05)


def _ti_network() -> RCNetwork:
    return RCNetwork(
        "ti", inputs=(("Ta", "ambient", "temperature"), ("Phi", "heating", "heat")), states=(("Ti", "Ci"),),
        couplings=(("Ti", "Ta", "Ria"),), heat=(("Ti", "Phi", ""),), noise=(("Ti", "sigma_ti"),),
        outputs=(("y", "Ti", "sigma_y"),),
        params=(Param("Ci", 2.0, 1e-3, 1e3), Param("Ria", 3.0, 1e-3, 1e3), Param("sigma_ti", 0.2, 1e-4, 10.0),
                Param("sigma_y", 0.05, 1e-4, 5.0)))


def _inputs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.25
    ta = 5 + 4 * np.sin(2 * np.pi * t / 24) + np.cumsum(rng.normal(0, 0.1, n))
    phi = np.where(np.sin(2 * np.pi * t / 7.3) > 0.2, 4.0, 0.0)
    return t, np.column_stack([ta, phi])


def test_fit_recovers_parameters_within_intervals_and_the_filter_is_white():
    net = _ti_network()
    t, u = _inputs(1500, 1)
    true = {"Ci": 2.0, "Ria": 3.0, "sigma_ti": 0.2, "sigma_y": 0.05}
    y = sto.simulate(net.system(true), sto.Series.of(t, u, np.full(len(t), 15.0)), seed=4)
    data = sto.Series.of(t, u, y)
    est = sto.fit(net.with_values({"Ci": 6.0, "Ria": 1.0, "sigma_ti": 1.0, "sigma_y": 0.3}), data, seed=0, starts=2)
    for name in ("Ci", "Ria", "sigma_ti"):
        lo, hi = est.intervals[name]
        assert lo < true[name] < hi, (name, est.values[name], lo, hi)
        assert lo < est.values[name] < hi
    assert not {"Ci", "Ria"} & set(est.unidentifiable)
    htc, (lo, hi) = est.derived(lambda v: 1.0 / v["Ria"])
    assert lo < 1 / 3.0 < hi and htc == pytest.approx(1 / est.values["Ria"])
    assert est.loglik >= loglik(net, data, true) - 1e-6
    f = est.filtered()
    assert whiteness.summary(f.standardized[:, 0])["white"]


def test_a_parameter_that_only_enters_through_a_sum_is_named_unidentifiable():
    net = _ti_network()
    t, u = _inputs(800, 2)
    y = sto.simulate(net.system(), sto.Series.of(t, u, np.full(len(t), 15.0)), seed=5)
    twin = RCNetwork(net.name, net.inputs, net.states, net.couplings + (("Ti", "Ta", "Rb"),), net.heat, net.noise,
                     net.outputs, net.params + (Param("Rb", 30.0, 1e-3, 1e3),))
    est = sto.fit(twin, sto.Series.of(t, u, y), seed=0, starts=1)
    assert {"Ria", "Rb"} & set(est.unidentifiable)  # only 1/Ria + 1/Rb is seen
    assert "sigma_ti" not in est.unidentifiable


def test_k_step_predictions_start_from_the_filtered_state():
    s = two_state()
    t = np.arange(200) * 0.5
    u = np.random.default_rng(0).normal(size=(200, 2))
    data = sto.Series.of(t, u, sto.simulate(s, sto.Series.of(t, u, np.zeros(200)), seed=1))
    f = kalman.run(s, data)
    one = sto.k_step(s, data, f, 1)
    assert np.isnan(one[0]).all()
    assert np.allclose(one[1:, 0], f.x_pred[1:] @ s.C[0])  # one step ahead = the filter's prediction
    ten = sto.k_step(s, data, f, 10)
    Phi, Gam, _ = s.discrete(0, 0.5)
    x = f.x_filt[40]
    for k in range(40, 50):
        x = Phi @ x + Gam @ u[k]
    assert ten[50, 0] == pytest.approx(s.C[0] @ x)
    err = lambda p: np.sqrt(np.nanmean((p[10:, 0] - data.y[10:, 0]) ** 2))  # noqa: E731
    assert err(one) < err(ten)


def test_whiteness_passes_white_noise_and_fails_an_ar1():
    rng = np.random.default_rng(7)
    e = rng.normal(size=3000)
    assert whiteness.summary(e)["white"]
    ar = np.empty(3000)
    ar[0] = 0
    for k in range(1, 3000):
        ar[k] = 0.5 * ar[k - 1] + e[k]
    w = whiteness.summary(ar)
    assert not w["white"] and w["acf_lag1"] == pytest.approx(0.5, abs=0.05) and w["cp_max_dev"] > w["cp_bound"]
    f, C, ks = whiteness.cumulated_periodogram(e)
    assert C[-1] == pytest.approx(1.0) and ks == pytest.approx(1.358 / math.sqrt(len(f) - 1))


def test_transformations_round_trip_and_respect_bounds():
    for p in (Param("a", 2.0), Param("b", 2.0, 1e-3, 1e3), Param("c", 0.2, -1.0, 1.0),
              Param("d", -3.0, -math.inf, math.inf)):
        assert p.from_eta(p.to_eta(p.value)) == pytest.approx(p.value)
        for eta in (-50.0, 50.0):
            assert p.low <= p.from_eta(eta) <= p.high


@pytest.mark.parametrize("a", [0.5, 4.0, 1e4])
def test_the_step_noise_is_exact_for_slow_and_stiff_states(a):
    """dx = −a x dt + σ dW: Q_Δ = σ²/(2a)(1 − e^{−2aΔ}), also where Van Loan's block would overflow (aΔ = 2500)."""
    sigma, dt = 0.3, 0.25
    s = System(np.array([[[-a]]]), np.zeros((1, 1, 1)), np.eye(1), np.zeros((1, 1)), np.array([sigma]),
               np.array([0.1]))
    _, _, Q = s.discrete(0, dt)
    assert np.isfinite(Q).all()
    assert Q[0, 0] == pytest.approx(sigma ** 2 / (2 * a) * (1 - math.exp(-2 * a * dt)), rel=1e-9)
