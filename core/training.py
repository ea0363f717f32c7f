"""The shared torch trainer behind every torch model (the trainer side of RBMO-X, see design/optimizers.md).

One recipe for all networks: Z-scored inputs and targets, AdamW, ``CosineAnnealingWarmRestarts`` (SGDR)
stepped per batch, ``clip_grad_norm_``, and a chronological validation tail of the training data. Fitness
(validation RMSE in µm) is read only at SGDR cycle ends, where the learning rate has annealed to its minimum
and the weights are settled; early stopping, the kept checkpoint and Optuna pruning reports use those reads.
A non-finite loss or a gradient norm that stays huge raises :class:`DivergedError`, which a study records as
a failed trial flagged ``diverged``.

Models stay unaware of Optuna: a study wraps ``model.fit(...)`` in :func:`reporting`; inside it the trainer
calls ``trial.report(val_rmse_um, step=epoch)`` at cycle ends and raises ``optuna.TrialPruned`` when the
pruner says so. Outside the context nothing is reported.

A torch model subclasses :class:`TorchThermalModel`: its constructor takes its own hyper-parameters plus
``trainer`` (overrides of :class:`TrainerSettings`, a dict or a settings object; None keeps the class's
``trainer_defaults``) and ``random_state``, and it implements ``_build(n_inputs, n_outputs) -> nn.Module``.
Trainer fields are nested scikit-learn parameters: ``get_params()`` lists ``trainer__lr_max`` and the like,
``set_params(trainer__lr_max=0.05)`` and ``registry.create("model", name, trainer__lr_max=0.05)`` set them,
and a search space tunes them under those names (:func:`trainer_search_space`). torch is imported where
training or prediction starts, not with this module, so loading the plugins (``thermodrift plugins``) does
not pay for importing torch.

Determinism: training runs under :func:`seeded`, which seeds torch and numpy from ``random_state`` and
restores the callers' generator states afterwards. On CPU, equal seeds give bit-identical weights for a fixed
``torch.get_num_threads()`` (left to the caller) on the same kind of CPU: torch picks its kernels by instruction
set (``torch.backends.cpu.get_cpu_capability()``), and kernels of another set round differently, so a search
that reads the losses (which trials diverge, which is best) can take another path there. CUDA kernels are not
guaranteed deterministic.
"""

from __future__ import annotations

import contextvars
import copy
import dataclasses
import math
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Iterator

import numpy as np
import optuna
import pandas as pd

from thermodrift.core.components import ThermalModel

if TYPE_CHECKING:
    import torch
    from torch import nn

# Stabilisers that RBMO-X tunes together with each network's own parameters (design/optimizers.md).
_TRAINER_SEARCH_SPACE: dict[str, dict[str, Any]] = {
    "lr_max": {"type": "float", "low": 1e-4, "high": 1e-1, "log": True},
    "eta_min_ratio": {"type": "float", "low": 1e-3, "high": 0.5, "log": True},
    "t0": {"type": "int", "low": 5, "high": 50},
    "t_mult": {"type": "int", "low": 1, "high": 3},
    "clip_norm": {"type": "float", "low": 0.1, "high": 10.0, "log": True},
}
TRAINER = "trainer"  # the constructor parameter of torch models that holds trainer settings
_NESTED = f"{TRAINER}__"


def trainer_search_space() -> dict[str, dict[str, Any]]:
    """The stabilisers' search space as nested model parameters (``trainer__lr_max``, ``trainer__eta_min_ratio``,
    ``trainer__t0``, ``trainer__t_mult``, ``trainer__clip_norm``), a fresh copy per call."""
    return {_NESTED + k: v for k, v in copy.deepcopy(_TRAINER_SEARCH_SPACE).items()}


LOSSES = ("mse", "mae", "rmse")


def loss_function(name: str) -> Callable[[torch.Tensor, torch.Tensor], torch.Tensor]:
    """The training loss ``name`` (one of :data:`LOSSES`) on standardised targets."""
    import torch
    from torch.nn import functional

    losses = {
        "mse": functional.mse_loss,
        "mae": functional.l1_loss,
        # The epsilon keeps the gradient finite when a batch is fitted exactly.
        "rmse": lambda pred, target: torch.sqrt(functional.mse_loss(pred, target) + 1e-12),
    }
    return losses[name]


_PREDICT_CHUNK = 65_536  # rows per forward pass at prediction time, bounds memory on long recordings


class DivergedError(RuntimeError):
    """Training blew up (non-finite loss or persistently huge gradient norm); ``report`` holds what ran."""

    def __init__(self, message: str, report: "TrainReport"):
        super().__init__(message)
        self.report = report


@dataclass(frozen=True)
class TrainerSettings:
    """Trainer settings. Learning rates are per standardised unit; ``patience`` counts cycle ends.

    ``batch_size`` None trains full-batch. ``clip_norm`` None disables clipping (norms are still recorded).
    ``validation_fraction`` is the chronological tail of the training data held out for fitness; 0 reads
    fitness on the training data instead. ``patience`` None disables early stopping. Training is declared
    diverged after ``diverge_steps`` consecutive steps with a gradient norm above ``diverge_grad_norm``.
    """

    lr_max: float = 1e-2
    weight_decay: float = 1e-4
    epochs: int = 300
    batch_size: int | None = None
    t0: int = 20
    t_mult: int = 2
    eta_min_ratio: float = 1e-2
    clip_norm: float | None = 1.0
    patience: int | None = 3
    validation_fraction: float = 0.15
    loss: str = "mse"
    device: str = "auto"
    diverge_grad_norm: float = 1e4
    diverge_steps: int = 10

    def __post_init__(self) -> None:
        checks = {
            "lr_max must be > 0": self.lr_max > 0,
            "weight_decay must be >= 0": self.weight_decay >= 0,
            "epochs must be >= 1": self.epochs >= 1,
            "batch_size must be None or >= 1": self.batch_size is None or self.batch_size >= 1,
            "t0 must be >= 1": self.t0 >= 1,
            "t_mult must be >= 1": self.t_mult >= 1,
            "eta_min_ratio must be in [0, 1]": 0 <= self.eta_min_ratio <= 1,
            "clip_norm must be None or > 0": self.clip_norm is None or self.clip_norm > 0,
            "patience must be None or >= 1": self.patience is None or self.patience >= 1,
            "validation_fraction must be in [0, 0.5]": 0 <= self.validation_fraction <= 0.5,
            f"loss must be one of {sorted(LOSSES)}": self.loss in LOSSES,
            "diverge_steps must be >= 1": self.diverge_steps >= 1,
        }
        failed = [msg for msg, ok in checks.items() if not ok]
        if failed:
            raise ValueError("; ".join(failed))


@dataclass
class TrainReport:
    """What one training run did. Grad norms are the total L2 norms before clipping."""

    epochs_run: int = 0
    steps: int = 0
    best_epoch: int = 0
    best_val_rmse_um: float = math.inf
    val_rmse_um: dict[int, float] = field(default_factory=dict)  # epoch -> RMSE at each read point (µm)
    cycle_ends: list[int] = field(default_factory=list)  # SGDR cycle ends within the epoch budget
    stopped_early: bool = False
    grad_norm_mean: float = math.nan
    grad_norm_max: float = math.nan
    clipped_fraction: float = math.nan
    seconds: float = 0.0
    n_parameters: int = 0  # trainable weights of the network

    def metrics(self) -> dict[str, float]:
        """Scalar fields for a tracker (booleans as 0/1)."""
        return {k: float(v) for k, v in dataclasses.asdict(self).items() if isinstance(v, (int, float, bool))}


@dataclass(frozen=True)
class Standardizer:
    """Z-score over every axis but the last (the feature axis); constant features get a scale of 1."""

    mean: np.ndarray
    scale: np.ndarray

    @classmethod
    def fit(cls, a: np.ndarray) -> "Standardizer":
        flat = np.asarray(a, dtype=float).reshape(-1, np.shape(a)[-1])
        scale = flat.std(axis=0)
        return cls(flat.mean(axis=0), np.where(scale > 0, scale, 1.0))

    def transform(self, a: np.ndarray) -> np.ndarray:
        return (np.asarray(a, dtype=float) - self.mean) / self.scale

    def inverse(self, a: np.ndarray) -> np.ndarray:
        return np.asarray(a, dtype=float) * self.scale + self.mean


@dataclass
class TrainResult:
    """Best weights (CPU state dict), the scalers they expect, and the report."""

    state_dict: dict[str, torch.Tensor]
    x_scaler: Standardizer
    y_scaler: Standardizer
    report: TrainReport


# ---------------------------------------------------------------------------------------------------- reporting
_TRIAL: contextvars.ContextVar[Any] = contextvars.ContextVar("thermodrift_trial", default=None)


@contextmanager
def reporting(trial: optuna.trial.BaseTrial) -> Iterator[optuna.trial.BaseTrial]:
    """Inside this block, training reports validation RMSE (µm) to ``trial`` at cycle ends and may be pruned."""
    token = _TRIAL.set(trial)
    try:
        yield trial
    finally:
        _TRIAL.reset(token)


def _report_to_trial(val_rmse_um: float, epoch: int) -> None:
    trial = _TRIAL.get()
    if trial is None:
        return
    trial.report(val_rmse_um, step=epoch)
    if trial.should_prune():
        raise optuna.TrialPruned(f"pruned at epoch {epoch} (validation RMSE {val_rmse_um:.4g} µm)")


# ---------------------------------------------------------------------------------------------------- helpers
def cycle_ends(t0: int, t_mult: int, epochs: int) -> list[int]:
    """Epoch counts at which SGDR cycles of lengths t0, t0·t_mult, t0·t_mult², ... end, up to ``epochs``."""
    ends, length, end = [], t0, t0
    while end <= epochs:
        ends.append(end)
        length *= t_mult
        end += length
    return ends


def resolve_device(device: str) -> torch.device:
    """``"auto"`` is CUDA when available, else CPU; anything else is passed to ``torch.device``."""
    import torch

    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(device)


def set_num_threads(threads: int) -> None:
    """Set torch's CPU threads for this process (1 is fastest for small thermal networks)."""
    import torch

    torch.set_num_threads(threads)


@contextmanager
def seeded(seed: int, device: torch.device | None = None) -> Iterator[None]:
    """Seed torch (CPU and ``device``) and numpy's global generator; restore the previous states on exit."""
    import torch

    np_state = np.random.get_state()
    cuda = []
    if device is not None and device.type == "cuda":
        cuda = [device.index if device.index is not None else torch.cuda.current_device()]
    with torch.random.fork_rng(devices=cuda, device_type="cuda"):
        torch.random.default_generator.manual_seed(seed)
        for index in cuda:
            with torch.cuda.device(index):
                torch.cuda.manual_seed(seed)
        np.random.seed(seed % 2**32)
        try:
            yield
        finally:
            np.random.set_state(np_state)


class _GradNormLog:
    """Running statistics of per-step gradient norms, and the divergence guard on them."""

    def __init__(self, clip_norm: float | None, diverge_grad_norm: float, diverge_steps: int):
        self.clip_norm, self.limit, self.patience = clip_norm, diverge_grad_norm, diverge_steps
        self.steps, self.total, self.max, self.clipped, self.run_above = 0, 0.0, 0.0, 0, 0

    def add(self, losses: list[float], norms: list[float]) -> str | None:
        """Record one epoch's steps; return why training diverged, or None."""
        for loss, norm in zip(losses, norms):
            self.steps += 1
            if not math.isfinite(loss) or not math.isfinite(norm):
                return f"non-finite loss or gradient at step {self.steps} (loss {loss:.3g}, grad norm {norm:.3g})"
            self.total += norm
            self.max = max(self.max, norm)
            self.clipped += self.clip_norm is not None and norm > self.clip_norm
            self.run_above = self.run_above + 1 if norm > self.limit else 0
            if self.run_above >= self.patience:
                return (f"gradient norm above {self.limit:g} for {self.run_above} consecutive steps "
                        f"(step {self.steps}, norm {norm:.3g})")
        return None

    def fill(self, report: TrainReport) -> None:
        if self.steps:
            report.steps = self.steps
            report.grad_norm_mean = self.total / self.steps
            report.grad_norm_max = self.max
            report.clipped_fraction = self.clipped / self.steps


def _rmse_um(module: nn.Module, x: torch.Tensor, y: torch.Tensor, y_scale: torch.Tensor) -> float:
    import torch

    module.eval()
    with torch.no_grad():
        err = (module(x) - y) * y_scale
    module.train()
    return float(err.pow(2).mean().sqrt())


def _step(params: list[nn.Parameter], optimizer: torch.optim.Optimizer, loss: torch.Tensor,
          clip_norm: float | None) -> tuple[torch.Tensor, torch.Tensor]:
    """Backward, clip and update; returns the loss and the gradient norm before clipping (device tensors)."""
    from torch.nn.utils import clip_grad_norm_, get_total_norm

    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    if clip_norm is None:
        norm = get_total_norm([p.grad for p in params if p.grad is not None])
    else:
        norm = clip_grad_norm_(params, clip_norm)
    optimizer.step()
    return loss.detach(), norm.detach()


# ---------------------------------------------------------------------------------------------------- training
def training_rows(n_samples: int, config: TrainerSettings) -> int:
    """How many of ``n_samples`` time-ordered samples :func:`train` fits on; the rest, the last
    ``validation_fraction`` of them (at least one when the fraction is above 0), is the validation tail."""
    n_val = max(1, round(config.validation_fraction * n_samples)) if config.validation_fraction > 0 else 0
    if n_samples - n_val < 1:
        raise ValueError(f"{n_samples} samples are too few for validation_fraction={config.validation_fraction}")
    return n_samples - n_val


def train(build: Callable[[], nn.Module], X: np.ndarray, y: np.ndarray, config: TrainerSettings, *,
          random_state: int = 0) -> TrainResult:
    """Train the module that ``build()`` returns on inputs ``X`` (n, ..., features) and targets ``y`` (n, k) µm,
    seeding weights and batch order from ``random_state``.

    Samples must be in time order: the last ``validation_fraction`` of them is the validation tail.
    Returns the weights of the best read point. Raises :class:`DivergedError` on divergence and
    ``optuna.TrialPruned`` when pruned inside :func:`reporting`.
    """
    import torch
    from torch.optim.lr_scheduler import CosineAnnealingWarmRestarts

    X, y = np.asarray(X, dtype=float), np.asarray(y, dtype=float).reshape(len(X), -1)
    if not (np.isfinite(X).all() and np.isfinite(y).all()):
        raise ValueError("training data contain NaN or infinite values")
    n_train = training_rows(len(X), config)
    n_val = len(X) - n_train
    x_scaler, y_scaler = Standardizer.fit(X[:n_train]), Standardizer.fit(y[:n_train])
    device = resolve_device(config.device)

    def tensor(a: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(a, dtype=torch.float32, device=device)

    xs, ys = tensor(x_scaler.transform(X)), tensor(y_scaler.transform(y))
    x_tr, y_tr = xs[:n_train], ys[:n_train]
    x_val, y_val = (xs[n_train:], ys[n_train:]) if n_val else (x_tr, y_tr)
    y_scale = tensor(y_scaler.scale)
    batch = n_train if config.batch_size is None else min(config.batch_size, n_train)
    n_batches = math.ceil(n_train / batch)

    report = TrainReport(cycle_ends=cycle_ends(config.t0, config.t_mult, config.epochs))
    read_points = set(report.cycle_ends) | {config.epochs}
    grad_log = _GradNormLog(config.clip_norm, config.diverge_grad_norm, config.diverge_steps)
    loss_fn = loss_function(config.loss)
    started = time.perf_counter()

    with seeded(random_state, device):
        module = build().to(device)
        module.train()
        params = [p for p in module.parameters() if p.requires_grad]
        report.n_parameters = sum(p.numel() for p in params)
        optimizer = torch.optim.AdamW(params, lr=config.lr_max, weight_decay=config.weight_decay)
        scheduler = CosineAnnealingWarmRestarts(optimizer, T_0=config.t0, T_mult=config.t_mult,
                                                eta_min=config.eta_min_ratio * config.lr_max)
        shuffle = torch.Generator().manual_seed(random_state)
        best_state: dict[str, torch.Tensor] = {}
        stale = 0
        for epoch in range(config.epochs):
            order = torch.randperm(n_train, generator=shuffle).to(device) if n_batches > 1 else None
            batches = [(x_tr, y_tr)] if order is None else [
                (x_tr[idx], y_tr[idx]) for idx in order.split(batch)]
            losses, norms = [], []
            for i, (xb, yb) in enumerate(batches):
                scheduler.step(epoch + i / n_batches)  # SGDR per batch: the lr anneals within each epoch
                loss, norm = _step(params, optimizer, loss_fn(module(xb), yb), config.clip_norm)
                losses.append(loss)
                norms.append(norm)
            # One host sync per epoch: the guard looks at the whole epoch's steps at once.
            reason = grad_log.add(torch.stack(losses).tolist(), torch.stack(norms).tolist())
            report.epochs_run = epoch + 1
            if reason is None and report.epochs_run in read_points:
                val = _rmse_um(module, x_val, y_val, y_scale)
                report.val_rmse_um[report.epochs_run] = val
                if not math.isfinite(val):
                    reason = f"non-finite validation RMSE at epoch {report.epochs_run}"
            if reason is not None:
                grad_log.fill(report)
                report.seconds = time.perf_counter() - started
                raise DivergedError(f"training diverged: {reason}", report)
            if report.epochs_run not in read_points:
                continue
            if val < report.best_val_rmse_um:
                report.best_val_rmse_um, report.best_epoch, stale = val, report.epochs_run, 0
                best_state = {k: v.detach().clone() for k, v in module.state_dict().items()}
            else:
                stale += 1
            if report.epochs_run in report.cycle_ends:
                _report_to_trial(val, report.epochs_run)
                if config.patience is not None and stale >= config.patience:
                    report.stopped_early = report.epochs_run < config.epochs
                    break

    grad_log.fill(report)
    report.seconds = time.perf_counter() - started
    return TrainResult({k: v.cpu() for k, v in best_state.items()}, x_scaler, y_scaler, report)


def predict(module: nn.Module, X: np.ndarray, x_scaler: Standardizer, y_scaler: Standardizer,
            device: torch.device) -> np.ndarray:
    """Run ``module`` on raw inputs ``X`` in chunks and return outputs in target units (µm)."""
    import torch

    xs = x_scaler.transform(X)
    module = module.to(device).eval()
    outs = []
    with torch.no_grad():
        for start in range(0, len(xs), _PREDICT_CHUNK):
            chunk = torch.as_tensor(xs[start:start + _PREDICT_CHUNK], dtype=torch.float32, device=device)
            outs.append(module(chunk).cpu().numpy())
    out = np.concatenate(outs) if outs else np.zeros((0, len(y_scaler.mean)))
    return y_scaler.inverse(out)


# ---------------------------------------------------------------------------------------------------- base model
class TorchThermalModel(ThermalModel):
    """Base for torch models trained by :func:`train`; a subclass states only its own hyper-parameters.

    A subclass's ``__init__`` takes its own hyper-parameters, then ``trainer=None`` and ``random_state=0``, and
    stores each unchanged; it implements ``_build(n_inputs, n_outputs)`` and may set the class attribute
    ``trainer_defaults`` (a :class:`TrainerSettings`) to change the defaults of its trainer. ``trainer`` holds
    overrides of those defaults (a dict of :class:`TrainerSettings` fields, a settings object, or None).
    Sequence models override ``_inputs(X)`` to return windows shaped (n, window, features). Fitted
    attributes: ``state_dict_`` (CPU tensors, so the model pickles without live optimisers), ``x_scaler_``,
    ``y_scaler_``, ``train_report_``.
    """

    trainer_defaults: ClassVar[TrainerSettings] = TrainerSettings()

    def _build(self, n_inputs: int, n_outputs: int) -> nn.Module:
        raise NotImplementedError

    def _inputs(self, X: pd.DataFrame) -> np.ndarray:
        return X.to_numpy(dtype=float)

    def trainer_settings(self) -> TrainerSettings:
        """The class's ``trainer_defaults`` with this model's ``trainer`` overrides applied."""
        overrides = _overrides(getattr(self, TRAINER, None))
        unknown = sorted(set(overrides) - _TRAINER_FIELDS)
        if unknown:
            raise ValueError(f"unknown trainer settings {unknown}; known: {', '.join(sorted(_TRAINER_FIELDS))}")
        return dataclasses.replace(self.trainer_defaults, **overrides)

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """Constructor parameters; with ``deep`` also every trainer field as ``trainer__<field>``."""
        params = super().get_params(deep=False)
        if deep:
            params.update({_NESTED + k: v for k, v in dataclasses.asdict(self.trainer_settings()).items()})
        return params

    def set_params(self, **params: Any) -> "TorchThermalModel":
        """Set constructor parameters; ``trainer__<field>=value`` adds to the ``trainer`` overrides."""
        nested = {k[len(_NESTED):]: params.pop(k) for k in list(params) if k.startswith(_NESTED)}
        super().set_params(**params)
        if nested:  # a new dict: a shared default or the caller's mapping is never changed in place
            setattr(self, TRAINER, {**_overrides(getattr(self, TRAINER, None)), **nested})
        return self

    def _fit(self, X: pd.DataFrame, y: np.ndarray) -> None:
        inputs = self._inputs(X)
        measured = np.isfinite(y).all(axis=1)
        if not measured.all():  # a sparse target (sequence models): inputs at full rate, trained where measured
            inputs, y = inputs[measured], y[measured]
        result = train(lambda: self._build(inputs.shape[-1], y.shape[1]), inputs, y, self.trainer_settings(),
                       random_state=self.random_state)
        self.state_dict_ = result.state_dict
        self.x_scaler_, self.y_scaler_ = result.x_scaler, result.y_scaler
        self.train_report_ = result.report

    def _predict(self, X: pd.DataFrame) -> np.ndarray:
        import torch

        with torch.random.fork_rng(devices=[]):  # building re-initialises weights; keep the caller's RNG intact
            module = self._build(len(self.x_scaler_.mean), len(self.y_scaler_.mean))
        module.load_state_dict(self.state_dict_)
        return predict(module, self._inputs(X), self.x_scaler_, self.y_scaler_,
                       resolve_device(self.trainer_settings().device))

    def export_state(self) -> dict[str, Any]:
        """Runtime ``sequence`` (architecture ``torch.export``): the network traced by ``torch.export`` for one
        sample (``window`` rows for sequence models), its graph as JSON bytes and its weights as tensors, and the
        scalers; :mod:`thermodrift.compensator.networks` runs it without this class."""
        import io

        import torch
        from torch._export.serde import serialize as serde

        with torch.random.fork_rng(devices=[]):  # building re-initialises weights; keep the caller's RNG intact
            module = self._build(len(self.x_scaler_.mean), len(self.y_scaler_.mean))
        module.load_state_dict(self.state_dict_)
        sample = self._inputs(pd.DataFrame(np.zeros((1, len(self.feature_names_in_))), columns=self.feature_names_in_))
        window = int(sample.shape[1]) if sample.ndim == 3 else None
        with warnings.catch_warnings():  # torch notes that nn.LSTM sets its flat weights while traced; harmless
            warnings.filterwarnings("ignore", message=".*were assigned during export", category=UserWarning)
            program = torch.export.export(module.eval(), (torch.zeros(sample.shape),))
        art = serde.serialize(program)

        def tensors(blob: bytes):
            return torch.load(io.BytesIO(blob), weights_only=True) if blob else {}

        weights = tensors(art.state_dict)
        return {"runtime": "sequence", "architecture": "torch.export", "window": window,
                "inputs": [str(c) for c in self.feature_names_in_], "targets": list(self.target_names_),
                "history_length": self.history_length,
                "program": np.frombuffer(art.exported_program, dtype=np.uint8).copy(),
                "weights": dict(weights),
                "parameters": [k for k, v in weights.items() if isinstance(v, torch.nn.Parameter)],
                "constants": dict(tensors(art.constants)),
                "x_mean": np.asarray(self.x_scaler_.mean), "x_scale": np.asarray(self.x_scaler_.scale),
                "y_mean": np.asarray(self.y_scaler_.mean), "y_scale": np.asarray(self.y_scaler_.scale)}


_TRAINER_FIELDS = frozenset(f.name for f in dataclasses.fields(TrainerSettings))


def _overrides(trainer: TrainerSettings | dict[str, Any] | None) -> dict[str, Any]:
    if trainer is None:
        return {}
    if isinstance(trainer, TrainerSettings):
        return dataclasses.asdict(trainer)
    return dict(trainer)
