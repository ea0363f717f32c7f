"""sensor_lag — temperature sensors that lag the metal (a probe in a bore, a magnetic sensor on paint).

Adds ``lag_s`` to the first-order time constant of the chosen temperature sensors (option ``sensors``; default
every sensor of role ``temperature``). Node temperatures and displacements are unchanged; readings are not.

Parameters: ``lag_s`` = 120 [0, 1800] s (neutral 0).
Direction: readings rise later and overshoot less at speed steps; the reading lags the node by ≈ τ_s·dT/dt.
Residual signature when missing: residual ≈ −τ_s·dT/dt: derivative spikes at speed steps. Test: regress on
dT/dt; fit a lag per sensor.
"""

import dataclasses

from thermodrift.core.errors import InputError
from thermodrift.core.hookspecs import hookimpl
from thermodrift.core.physics.mechanisms import FreeParameter, Mechanism, Parameter


class SensorLag(Mechanism):
    id = "sensor_lag"
    summary = "temperature sensors that lag the metal (a probe in a bore, a magnetic sensor on paint)"
    experiment = "fast speed steps with a fast reference sensor beside the slow one"
    parameters = (Parameter("lag_s", 120.0, 0.0, 1800.0, "s", 0.0, "added first-order sensor time constant"),)
    options = {"sensors": None}
    signature = "residual ≈ −τ_s dT/dt: derivative spikes at speed steps"
    # its form against a simulation (diagnose --simulation; see thermodrift.core.physics.diagnose.sim_forms)
    simulation_form = {"driver": "sensor_lag", "taus_s": (120.0, 300.0, 600.0, 1200.0, 2400.0),
                       "reaches": ("temperature",)}

    def _apply(self, network, p, o):
        chosen = o["sensors"]
        sensors = [s for s in network.temperature_sensors
                   if (s.name in chosen if chosen else s.role == "temperature")]
        if not sensors:
            raise InputError(f"mechanism {self.id!r}: network {network.name!r} has no such temperature sensors")
        return network.replace(*[dataclasses.replace(s, lag_s=s.lag_s + p["lag_s"]) for s in sensors])

    @classmethod
    def places(cls, network):
        return [{"sensors": [s.name]} for s in network.temperature_sensors if s.role == "temperature"]

    def _declare(self, before, after, p, o):
        old = {s.name: s for s in before.temperature_sensors}
        chosen = [s for s in after.temperature_sensors if old[s.name].lag_s != s.lag_s]
        base = old[chosen[0].name].lag_s  # one place is one sensor; several share the added lag
        same = [s for s in chosen if old[s.name].lag_s == base]
        return [FreeParameter("lag_s", tuple(f"sensors.{s.name}.lag_s" for s in same), p["lag_s"],
                          max(1.0, p["lag_s"] * 1e-3), 1800.0, "s", offset=base)]


@hookimpl
def thermodrift_register_mechanisms(registry):
    registry.add("mechanism", SensorLag.id, SensorLag)
