"""The building RC library's base: mechanisms that extend a stochastic RC network state by state (Bacher &
Madsen 2011, "Identifying suitable models for the heat dynamics of buildings"; the CTSM-R / pySIP forms).

Time in hours, temperatures in °C; heat in the heating input's unit (kW: C in kWh/K, R in K/kW, apertures in m²
when irradiance is in kW/m²; a unitless heating signal puts them in that signal's units). Inputs: outdoor air
``Ta`` (role ``ambient``), solar irradiance ``Ps`` (``solar_irradiance``), heating ``Phi`` (``heating``).

The mechanisms (plugins ``building_*``), each adding one state or coupling with its own process noise:

* ``building_ti`` — interior Ti: Ci dTi = [(Ta − Ti)/Ria + Aw Ps + Phi] dt + σi dW (the one-state model);
* ``building_te`` — envelope Te between Ti and Ta: (Ti − Te)/Rie, (Ta − Te)/Rea, capacity Ce; Ti then loses heat
  through the envelope only (Ria is removed);
* ``building_th`` — heater Th: the heating enters Th (capacity Ch), which heats Ti through Rih;
* ``building_tm`` — thermal medium Tm (capacity Cm) exchanging with Ti through Rim;
* ``building_ts`` — sensor Ts (capacity Cs) exchanging with Ti through Ris; the measurement reads Ts;
* ``building_aeria`` — with an envelope: the solar aperture Ae on Te plus a direct interior–ambient resistance
  Ria.

:func:`structure_name` spells a network's structure in the field's order (Ti, Tm, Te, Th, Ts, then AeRia, e.g.
``TiTeTh``); :func:`htc` is its heat-transfer coefficient, the steady heat loss per kelvin of interior–ambient
difference (1 / the static gain from heating to the measured temperature).
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar, Mapping

import numpy as np

from thermodrift.core.errors import InputError
from thermodrift.core.physics.mechanisms import Mechanism, Parameter
from thermodrift.core.physics.stochastic.fit import Param
from thermodrift.core.physics.stochastic.rc import RCNetwork

ORDER = ("Ti", "Tm", "Te", "Th", "Ts")
AERIA = "AeRia"
# Mechanism id per structure part, in the field's order.
PARTS = {"Ti": "building_ti", "Tm": "building_tm", "Te": "building_te", "Th": "building_th", "Ts": "building_ts",
         AERIA: "building_aeria"}
SIGMA_LOW, SIGMA_HIGH = 1e-4, 10.0   # process noise, K/√h
R_LOW, R_HIGH = 1e-4, 1e4            # resistances, K per heat unit
C_LOW, C_HIGH = 1e-4, 1e5            # capacities, heat unit·h/K
A_LOW, A_HIGH = 1e-4, 1e4            # apertures, heat unit per irradiance unit


def structure_name(net: RCNetwork) -> str:
    """The structure's name: its states in the order Ti, Tm, Te, Th, Ts, then ``AeRia`` when present."""
    states = set(net.state_names)
    name = "".join(s for s in ORDER if s in states)
    return name + (AERIA if any(m["id"] == PARTS[AERIA] for m in net.mechanisms) else "")


def htc(net: RCNetwork, values: Mapping[str, float] | None = None) -> float:
    """Heat-transfer coefficient (heat unit per K): steady heating per kelvin of measured interior over outdoor
    temperature, 1 / (static gain from the heating input to the first output)."""
    system = net.system(values)
    gain = system.static_gain()[0, net.input_names.index(net.input_of("heating"))]
    return float(1.0 / gain) if gain > 0 else float("nan")


def rescaled(net: RCNetwork, factor: float) -> RCNetwork:
    """Start values for a building whose heat scale is ``factor`` times the defaults': resistances divided,
    capacities and apertures multiplied (time constants and noise unchanged)."""
    out = {}
    for p in net.params:
        kind = p.name[0]
        if kind == "R":
            out[p.name] = p.value / factor
        elif kind in "CA":
            out[p.name] = p.value * factor
    return net.with_values(out)


def _p(name: str, default: float, low: float, high: float, unit: str, doc: str) -> Parameter:
    return Parameter(name, default, low, high, unit, neutral=low, doc=doc)


def sigma(state: str, default: float = 0.1) -> Parameter:
    return _p(f"sigma_{state.lower()}", default, SIGMA_LOW, SIGMA_HIGH, "K/√h", f"process noise of {state}")


def measurement(name: str = "sigma_y", default: float = 0.05) -> Parameter:
    return _p(name, default, 1e-4, 5.0, "K", "measurement noise of the indoor temperature")


def resistance(name: str, default: float, doc: str) -> Parameter:
    return _p(name, default, R_LOW, R_HIGH, "K/kW", doc)


def capacity(name: str, default: float, doc: str) -> Parameter:
    return _p(name, default, C_LOW, C_HIGH, "kWh/K", doc)


def aperture(name: str, default: float, doc: str) -> Parameter:
    return _p(name, default, A_LOW, A_HIGH, "m²", doc)


class BuildingMechanism(Mechanism):
    """A mechanism on a stochastic RC network (:class:`RCNetwork`); on a machine's network it has no place.

    Subclasses set ``id``, ``parameters``, ``signature``, ``part`` (the structure part it adds) and implement
    ``_extend(net, p)`` and ``_applies(net)`` (whether it can extend ``net``)."""

    part: ClassVar[str] = ""

    @classmethod
    def places(cls, network) -> list[dict[str, Any]]:
        return [{}] if isinstance(network, RCNetwork) and cls._applies(network) else []

    @classmethod
    def unplaced(cls, network) -> str | None:
        if isinstance(network, RCNetwork):
            return None
        return "skipped: a building RC mechanism acts on a stochastic building network (interior state Ti), not here"

    @classmethod
    def _applies(cls, net: RCNetwork) -> bool:
        raise NotImplementedError

    def _apply(self, network, p: dict[str, float], o: dict[str, Any]) -> RCNetwork:
        if not isinstance(network, RCNetwork):
            raise InputError(f"mechanism {self.id!r} extends a stochastic building network (RCNetwork), not "
                             f"{type(network).__name__}")
        if not self._applies(network):
            raise InputError(f"mechanism {self.id!r} cannot extend {structure_name(network) or 'an empty network'}"
                             f" ({self.signature})")
        params = tuple(Param(q.name, p[q.name], q.low, q.high, q.unit, q.doc) for q in self.parameters)
        return self._extend(network.with_params(*params), p).used()

    def _extend(self, net: RCNetwork, p: dict[str, float]) -> RCNetwork:
        raise NotImplementedError

    def declare(self, network, **params: float):
        """:meth:`apply` plus the parameters it added (the stochastic fit searches every network parameter)."""
        out = self.apply(network, **params)
        return out, [q for q in out.params if q.name in {x.name for x in self.parameters}]


def replace(net: RCNetwork, **fields) -> RCNetwork:
    return dataclasses.replace(net, **fields)


def states_plus(net: RCNetwork, state: str, cap: str, sig: str) -> dict:
    """Fields of ``net`` with ``state`` (capacity ``cap``, process noise ``sig``) added."""
    return {"states": net.states + ((state, cap),), "noise": net.noise + ((state, sig),)}


def start_factor(heating: np.ndarray, y: np.ndarray, ambient: np.ndarray, default_htc: float) -> float:
    """Heat scale of a recording relative to the defaults: mean heating / mean (interior − outdoor) over the
    defaults' HTC (1 when either mean is not positive)."""
    dT, q = float(np.mean(y - ambient)), float(np.mean(heating))
    return q / dT / default_htc if dT > 0 and q > 0 else 1.0
