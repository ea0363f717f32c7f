"""The joint, conditional search space of ``thermodrift automl``: selector × input features × model family × the
family's hyper-parameters, over every registered model (third-party plugins included).

A candidate is a ``pipeline`` model's parameters (``model``, ``model_params``, ``selector``, ``selector_params``,
``features``) plus a fidelity (``rung``: epochs of a network, see :func:`at_rung`). A plugin may declare, as class
attributes, ``automl_cost`` ("cheap", "medium", "expensive"; "skip" leaves it out), ``automl_space`` (a
search space in :mod:`thermodrift.core.search_space` form replacing its ``search_space()`` here) and
``automl_features`` (whether a feature stage may feed it; never for models reading raw channels by role); without
them: a model trained by :mod:`thermodrift.core.training` (a network) is expensive,
every other one cheap. Models that read the measured target (``uses_target_history``: persistence) are
references, never candidates.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np
import optuna

from thermodrift.core import registry, search_space
from thermodrift.core.training import TorchThermalModel

COSTS = ("cheap", "medium", "expensive")
# Each component declares its own cost (``automl_cost``) and whether a feature stage may feed it
# (``automl_features``), built-in or third-party; the conformance suite checks the values (model_checks).
# Selectors: every registered one takes part unless it declares ``automl_cost = "skip"`` (slow or random).
# Feature stage: filter time constants (s) from tau_min_s to tau_max_s, geometric, and drive heat powers.
FEATURE_SPACE = {"tau_min_s": {"type": "float", "low": 120.0, "high": 3600.0, "log": True},
                 "tau_max_s": {"type": "float", "low": 3600.0, "high": 43200.0, "log": True},
                 "n_taus": {"type": "int", "low": 1, "high": 5},
                 "max_power": {"type": "int", "low": 1, "high": 3}}
DEFAULT_FEATURES = {"taus_s": [600.0, 2400.0, 9600.0], "powers": [1.0, 2.0]}
# Filter banks of the portfolio: time constants (s) a decade and more apart, one bank fast, one slow; every
# feature-taking family reads each (a machine's time constants are unknown before the data).
FILTER_BANKS = (DEFAULT_FEATURES, {"taus_s": [1200.0, 4800.0, 19200.0], "powers": [1.0, 2.0]})
# Regularisation path of the portfolio: a family whose space has an L2 penalty ``alpha`` reads the filter banks at
# these strengths (clipped into its space). Many collinear filtered columns extrapolate to a new working condition
# only under a penalty whose size the inner folds must decide, and a coarse path chosen on the folds is
# less prone to fit their noise than a finely tuned value.
ALPHA_PATH = (1.0, 10.0, 100.0)
RUNG_EPOCH_FACTOR = 3  # successive halving: each rung trains a network 3× longer and keeps a third


@dataclass(frozen=True)
class Family:
    """A model family taking part: its registry name, cost class, search space, and whether a feature stage
    may feed it (not for models that read raw channels by role, such as the physics families)."""

    name: str
    cost: str
    space: dict
    takes_features: bool
    network: bool


@dataclass
class Candidate:
    """One pipeline to try: ``params`` of the ``pipeline`` model, its fidelity ``rung`` and where it came from."""

    params: dict
    rung: int = 0
    origin: str = "tpe"
    label: str = ""

    @property
    def family(self) -> str:
        return self.params["model"]

    def to_json(self) -> str:
        return json.dumps({"params": self.params, "rung": self.rung, "origin": self.origin, "label": self.label},
                          default=str)

    @classmethod
    def from_json(cls, text: str) -> "Candidate":
        d = json.loads(text)
        return cls(d["params"], d.get("rung", 0), d.get("origin", "tpe"), d.get("label", ""))


def missing_roles(cls, roles) -> list[str]:
    """The roles of ``cls.requires_roles`` (what a model cannot run without, e.g. speed) absent from ``roles``."""
    return [r for r in getattr(cls, "requires_roles", ()) if r not in roles]


def left_out(roles, reg: registry.Registry | None = None, only: list[str] | None = None) -> dict[str, list[str]]:
    """Families that would take part but cannot run on a recording with channels of ``roles`` only: name -> the
    roles each lacks (read from the class's ``requires_roles``, before anything is fitted)."""
    reg = reg or registry.default()
    names = [f.name for f in families(reg, only)]
    return {n: miss for n in names if (miss := missing_roles(reg.get("model", n).factory, roles))}


def left_out_line(missing: dict[str, list[str]], source: str) -> str:
    """One line naming the families :func:`left_out` found and why (empty when none)."""
    by_roles: dict[tuple[str, ...], list[str]] = {}
    for name, roles in missing.items():
        by_roles.setdefault(tuple(roles), []).append(name)
    parts = [f"{', '.join(names)} (need{'s' if len(names) == 1 else ''} a channel of role {' and '.join(roles)})"
             for roles, names in by_roles.items()]
    return f"automl: left out before fitting, {source} has no such channel: {'; '.join(parts)}" if parts else ""


def families(reg: registry.Registry | None = None, only: list[str] | None = None,
             roles=None) -> list[Family]:
    """Every registered model that takes part (or those named in ``only``), in name order; with ``roles`` (the
    roles of the recording's channels), only those whose ``requires_roles`` it has (:func:`left_out` names the
    others)."""
    reg = reg or registry.default()
    for name in only or []:
        reg.get("model", name)  # an unknown name: one line with the known ones
    out = []
    for name in reg.names("model"):
        cls = reg.get("model", name).factory
        if getattr(cls, "uses_target_history", False):
            continue  # a reference (it reads the measured target), never a candidate
        if roles is not None and missing_roles(cls, roles):
            continue  # cannot run on this recording: left out before fitting
        cost = getattr(cls, "automl_cost", None)
        network = isinstance(cls, type) and issubclass(cls, TorchThermalModel)
        cost = cost or ("expensive" if network else "cheap")
        if only is not None:
            if name not in only:
                continue
            cost = "cheap" if cost == "skip" else cost
        if cost == "skip":
            continue
        space = getattr(cls, "automl_space", None)
        space = dict(cls.search_space() if space is None else space)
        search_space.distributions(space)
        reads = getattr(cls, "extra_input_roles", ())
        takes = getattr(cls, "automl_features", True) and "speed" not in reads \
            and "cutting_power" not in reads
        out.append(Family(name, cost if cost in COSTS else "cheap", space, takes, network))
    return out


def selectors(reg: registry.Registry | None = None) -> dict[str, dict]:
    """Selectors that take part with their search spaces (``all`` keeps every temperature channel)."""
    reg = reg or registry.default()
    out = {}
    for name in reg.names("selector"):
        cls = reg.get("selector", name).factory
        if getattr(cls, "automl_cost", None) == "skip":
            continue
        space = getattr(cls, "automl_space", None)
        out[name] = dict(cls.search_space() if space is None else space) if name != "all" else {}
    return out


def features_from(params: dict) -> dict:
    """Feature-stage parameters from the sampled ``tau_min_s``, ``tau_max_s``, ``n_taus``, ``max_power``."""
    n = int(params["n_taus"])
    taus = np.geomspace(params["tau_min_s"], max(params["tau_min_s"], params["tau_max_s"]), n)
    return {"taus_s": [round(float(t), 1) for t in taus],
            "powers": [float(p) for p in range(1, int(params["max_power"]) + 1)]}


def suggest(trial: optuna.Trial, fams: list[Family], sels: dict[str, dict]) -> Candidate:
    """A candidate drawn by ``trial`` from the conditional space (names ``<family>.<param>``, ``selector``,
    ``<selector>.<param>``, ``features``, ``features.<param>``)."""
    family = {f.name: f for f in fams}[trial.suggest_categorical("family", [f.name for f in fams])]
    model_params = {k.split(".", 1)[1]: v for k, v in search_space.suggest(
        trial, {f"{family.name}.{k}": v for k, v in family.space.items()}).items()}
    selector = trial.suggest_categorical("selector", sorted(sels))
    selector_params = {k.split(".", 1)[1]: v for k, v in search_space.suggest(
        trial, {f"{selector}.{k}": v for k, v in sels[selector].items()}).items()}
    features = None
    if family.takes_features and trial.suggest_categorical("features", ["raw", "filtered"]) == "filtered":
        features = features_from({k.split(".", 1)[1]: v for k, v in search_space.suggest(
            trial, {f"features.{k}": v for k, v in FEATURE_SPACE.items()}).items()})
    return Candidate(
        {"model": family.name, "model_params": _nested(model_params), "selector": selector,
         "selector_params": selector_params, "features": features})


def portfolio(fams: list[Family], sels: dict[str, dict]) -> list[Candidate]:
    """Known-good configurations first, cheapest first: every family untuned on all sensors; every family that
    takes features (networks aside) on each filter bank of :data:`FILTER_BANKS`, along :data:`ALPHA_PATH` where
    it has a ridge penalty; the cheap read-outs on filtered features of the correlation-selected sensors.
    Networks enter at the lowest fidelity (rung 0)."""
    order = {c: i for i, c in enumerate(COSTS)}
    ranked = sorted(fams, key=lambda f: (order[f.cost], f.name))
    out = []
    for cost in COSTS:  # per cost class: every family untuned, then the filter banks along the penalty path
        same = [f for f in ranked if f.cost == cost]
        out += [Candidate(_base(f.name), origin="portfolio", label="untuned, all sensors") for f in same]
        for f in same:
            if f.takes_features and not f.network:  # networks get features through TPE, if they make its list
                for bank, (mp, label) in ((b, m) for b in FILTER_BANKS for m in penalty_path(f)):
                    out.append(Candidate({**_base(f.name), "model_params": mp, "features": dict(bank)},
                                         origin="portfolio",
                                         label=f"filtered features ({bank['taus_s'][0]:g} s…){label}"))
    if "correlation_top_k" in sels:
        for f in ranked:
            if f.takes_features and f.cost == "cheap":
                mp, label = penalty_path(f)[0]
                out.append(Candidate({**_base(f.name), "model_params": mp, "selector": "correlation_top_k",
                                      "selector_params": {"k": 6}, "features": dict(DEFAULT_FEATURES)},
                                     origin="portfolio", label=f"6 sensors, filtered features{label}"))
    return out


def penalty_path(family: Family) -> list[tuple[dict, str]]:
    """(model parameters, label) along :data:`ALPHA_PATH` for a family with an ``alpha`` penalty in its space
    (clipped into its bounds, duplicates dropped), else its defaults alone."""
    spec = family.space.get("alpha")
    if not spec or spec.get("type") != "float":
        return [({}, "")]
    alphas = dict.fromkeys(float(np.clip(a, spec["low"], spec["high"])) for a in ALPHA_PATH)
    return [({"alpha": a}, f", alpha {a:g}") for a in alphas]


def at_rung(candidate: Candidate, rung: int, family: Family, top_rung: int) -> dict:
    """The pipeline parameters of ``candidate`` trained at ``rung``: a network's epochs are its default divided
    by ``RUNG_EPOCH_FACTOR`` once per rung below ``top_rung`` (at least 4); other families are unchanged."""
    params = json.loads(json.dumps(candidate.params))
    if not family.network:
        return params
    cls = registry.get("model", family.name).factory
    defaults = getattr(cls, "trainer_defaults", None)
    epochs = int(getattr(defaults, "epochs", 100) or 100)
    scaled = max(4, epochs // RUNG_EPOCH_FACTOR ** max(0, top_rung - rung))
    trainer = dict(params["model_params"].get("trainer") or {})
    trainer["epochs"] = min(int(trainer.get("epochs", epochs)), scaled)
    if "t0" in trainer or hasattr(defaults, "t0"):
        trainer["t0"] = max(1, min(int(trainer.get("t0", getattr(defaults, "t0", 1) or 1)), trainer["epochs"]))
    params["model_params"] = {**params["model_params"], "trainer": trainer}
    return params


def describe(params: dict) -> str:
    """A short label: ``mlr · correlation_top_k(k=6) · filtered(600,2400 s; p≤2)``."""
    sel = params.get("selector", "all")
    sp = params.get("selector_params") or {}
    sel = f"{sel}({', '.join(f'{k}={_fmt(v)}' for k, v in sp.items())})" if sp else sel
    feats = params.get("features")
    feat = "raw" if not feats else \
        f"filtered({','.join(f'{t:g}' for t in feats['taus_s'])} s; p≤{max(feats['powers']):g})"
    mp = settings(params)
    return f"{params['model']}({mp}) · {sel} · {feat}" if mp else f"{params['model']} · {sel} · {feat}"


def settings(params: dict) -> str:
    """The model's settings in a candidate's parameters, short (``alpha=0.01, n_taus=3``; empty: its defaults;
    a network's trainer settings left out)."""
    mp = {k: v for k, v in (params.get("model_params") or {}).items() if k != "trainer"}
    return ", ".join(f"{k}={_fmt(v)}" for k, v in mp.items())


def _fmt(v: Any) -> str:
    return f"{v:.3g}" if isinstance(v, float) else str(v)


def _base(name: str) -> dict:
    return {"model": name, "model_params": {}, "selector": "all", "selector_params": {}, "features": None}


def _nested(params: dict[str, Any]) -> dict[str, Any]:
    """``trainer__lr_max`` folded into a ``trainer`` dict, as the study does for the best parameters."""
    out: dict[str, Any] = {}
    for key, value in params.items():
        if "__" in key:
            outer, inner = key.split("__", 1)
            out.setdefault(outer, {})[inner] = value
        else:
            out[key] = value
    return out
