"""Model ``pso_bpnn``: S2's BP network whose initial weights and thresholds a particle swarm searches.

A swarm of ``swarm_size`` particles (S2: 20) flies for ``pso_iterations`` iterations (S2: 30) over every weight
and threshold (bias) of the ``bp`` network, each in [−``weight_bound``, ``weight_bound``]; a particle's fitness is
the network's MSE on the Z-scored training rows (the trainer's validation tail left out). The swarm is
thermodrift's own PSO sampler (``pso``) in S2's form, v ← 0.729 v + 1.49445 r1 (p − x) + 1.49445 r2 (g − x),
the constriction swarm χ = 0.729, c = 1.49445 written with an inertia weight; the whole swarm is evaluated in
one vectorised forward pass per iteration. Back-propagation on the shared trainer then fine-tunes from the
best particle. S2 also let the swarm choose the hidden structure: here the study's search space does that
(``hidden_units`` 3–13).
"""

from __future__ import annotations

import math

import numpy as np
import optuna
import pandas as pd
from optuna.distributions import FloatDistribution

from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.training import Standardizer, train, trainer_search_space, training_rows
from thermodrift.plugins.models.bp import BPNetwork


def _activation(name: str, z: np.ndarray) -> np.ndarray:
    if name == "tanh":
        return np.tanh(z)
    if name == "sigmoid":
        return 1.0 / (1.0 + np.exp(-z))
    if name == "relu":
        return np.maximum(z, 0.0)
    from scipy.special import erf

    return 0.5 * z * (1.0 + erf(z / math.sqrt(2.0)))  # gelu, exact form as torch's default


class PSOBPNN(BPNetwork):
    """:class:`~thermodrift.plugins.models.bp.BPNetwork` started from a PSO-searched point (module docstring).

    ``inertia``, ``c1``, ``c2``: the swarm's coefficients (S2's constriction values by default).
    """

    automl_cost = "skip"  # a swarm of networks per fit

    def __init__(self, hidden_layers: int = 2, hidden_units: int = 8, activation: str = "tanh",
                 swarm_size: int = 20, pso_iterations: int = 30, weight_bound: float = 1.0, inertia: float = 0.729,
                 c1: float = 1.49445, c2: float = 1.49445, trainer: dict | None = None, random_state: int = 0):
        super().__init__(hidden_layers=hidden_layers, hidden_units=hidden_units, activation=activation,
                         trainer=trainer, random_state=random_state)
        self.swarm_size = swarm_size
        self.pso_iterations = pso_iterations
        self.weight_bound = weight_bound
        self.inertia = inertia
        self.c1 = c1
        self.c2 = c2

    @classmethod
    def get_test_params(cls):
        return [{"hidden_units": 4, "swarm_size": 4, "pso_iterations": 3, "trainer": {"epochs": 6, "t0": 2}},
                {"hidden_layers": 1, "hidden_units": 3, "swarm_size": 3, "pso_iterations": 2,
                 "trainer": {"epochs": 4, "t0": 2, "t_mult": 1, "patience": None}}]

    @classmethod
    def search_space(cls):
        return {"hidden_layers": {"type": "int", "low": 1, "high": 2},
                "hidden_units": {"type": "int", "low": 3, "high": 13},
                "trainer__lr_max": trainer_search_space()["trainer__lr_max"]}

    def _fit(self, X: pd.DataFrame, y: np.ndarray) -> None:
        if self.swarm_size < 1 or self.pso_iterations < 1 or self.weight_bound <= 0:
            raise ValueError("swarm_size and pso_iterations must be >= 1 and weight_bound > 0")
        inputs = self._inputs(X)
        config = self.trainer_settings()
        # The trainer's own split and scaling (training.train): the swarm sees only the rows BP trains on.
        n_train = training_rows(len(inputs), config)
        xs = Standardizer.fit(inputs[:n_train]).transform(inputs[:n_train])
        ys = Standardizer.fit(y[:n_train]).transform(y[:n_train])
        start = self._swarm(xs, ys, inputs.shape[-1], y.shape[1])

        def build():
            module = self._build(inputs.shape[-1], y.shape[1])
            module.load_state_dict(start)
            return module

        result = train(build, inputs, y, config, random_state=self.random_state)
        self.state_dict_ = result.state_dict
        self.x_scaler_, self.y_scaler_ = result.x_scaler, result.y_scaler
        self.train_report_ = result.report

    def _swarm(self, xs: np.ndarray, ys: np.ndarray, n_in: int, n_out: int) -> dict:
        """The best initial state dict the swarm finds (its best MSE per iteration in ``swarm_curve_``)."""
        import torch

        from thermodrift.core import registry  # the registered sampler, as any plugin reaches another

        with torch.random.fork_rng(devices=[]):
            template = self._build(n_in, n_out).state_dict()
        shapes = [(k, tuple(v.shape)) for k, v in template.items()]
        dim = sum(int(np.prod(s)) for _, s in shapes)
        space = {f"w{i:05d}": FloatDistribution(-self.weight_bound, self.weight_bound) for i in range(dim)}
        sampler = registry.create_sampler("pso", seed=self.random_state,
                                          n_trials=self.swarm_size * self.pso_iterations,
                                          population_size=self.swarm_size, form="inertia", w_start=self.inertia,
                                          w_end=self.inertia, c1=self.c1, c2=self.c2)
        optuna.logging.set_verbosity(optuna.logging.WARNING)
        study = optuna.create_study(sampler=sampler, direction="minimize")
        names = list(space)
        curve = []
        for _ in range(self.pso_iterations):
            trials = [study.ask(space) for _ in range(self.swarm_size)]
            swarm = np.array([[t.params[n] for n in names] for t in trials])
            mse = self._swarm_mse(swarm, shapes, xs, ys)
            for trial, value in zip(trials, mse):
                study.tell(trial, float(value) if np.isfinite(value) else 1e12)
            curve.append(float(study.best_value))
        self.swarm_curve_ = curve
        best = np.array([study.best_params[n] for n in names])
        out, at = {}, 0
        for key, shape in shapes:
            size = int(np.prod(shape))
            out[key] = torch.as_tensor(best[at:at + size].reshape(shape), dtype=template[key].dtype)
            at += size
        return out

    def _swarm_mse(self, swarm: np.ndarray, shapes: list, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """MSE (Z-scored units) of each particle's network on (xs, ys), all particles in one pass."""
        h = np.broadcast_to(xs, (len(swarm), *xs.shape))
        at, layers = 0, []
        for key, shape in shapes:
            size = int(np.prod(shape))
            layers.append(swarm[:, at:at + size].reshape(len(swarm), *shape))
            at += size
        pairs = list(zip(layers[0::2], layers[1::2]))  # (weight (S, out, in), bias (S, out)) per Linear
        for i, (w, b) in enumerate(pairs):
            h = np.einsum("snj,soj->sno", h, w) + b[:, None, :]
            if i < len(pairs) - 1:
                h = _activation(self.activation, h)
        with np.errstate(over="ignore", invalid="ignore"):
            return ((h - ys[None]) ** 2).mean(axis=(1, 2))


@hookimpl
def thermodrift_register_models(registry):
    registry.add("model", "pso_bpnn", PSOBPNN)
