"""Lumped-parameter thermal simulation of machine tools (temperatures in °C, displacements in µm).

Public API::

    from thermodrift.core import physics

    net = physics.load_network("demo_spindle")          # conf/network/<name>.yaml or a YAML path
    scen = physics.scenarios.fl_thermal(dt_s=15)         # or physics.scenarios.build("s3_programme", dt_s=60)
    res = physics.simulate(net, scen)                    # exact exponential per operating level
    res.temperatures, res.displacements                  # DataFrames indexed by time_s (°C per node, µm per output)
    res.measure(seed=0)                                  # sensor readings: offsets, lag, noise, quantization
    res.to_recording(seed=0)                             # a thermodrift.core.recording.Recording
    physics.synthesize(net, scen, seed=0)                # recording + Pt100 offsets + ground truth (JSON-ready)
    physics.Scenario.from_recording(rec)                 # re-simulate a measured programme (calibration)

    net.parameters()                                     # {"edges.shaft-ambient.G_W_K": 0.8, ...}
    net2 = net.with_values({"nodes.shaft.capacity_J_K": 4000.0})   # calibration hook (new network)
    comp = physics.CompiledNetwork(net2)                 # reuse across simulations of one parameter set
    X = comp.trajectory(scen)                            # (samples, nodes) °C as an array: the fitting path
    Y = comp.displacements(X, scen.frame["speed_rpm"])         # (samples, outputs) µm
    comp.time_constants_s(speed_rpm=0)

    mech = registry.create("mechanism", "slow_structural_mode")    # see physics.Mechanism
    net3 = mech.apply(net, tau_h=6.0)
    physics.load_network("vmc_spindle_s2", skip_mechanisms=["slow_structural_mode"])  # a baseline missing one

Modules: :mod:`.network` (elements and :class:`Network`), :mod:`.integrate` (:func:`simulate`),
:mod:`.scenarios` (:class:`Scenario` and builders), :mod:`.sensors`, :mod:`.spec` (YAML schema),
:mod:`.mechanisms` (:class:`Mechanism` base), :mod:`.synthetic` (recordings with ground truth),
:mod:`.calibration` (fitting a network to a recording; its docstring is the API), :mod:`.mismatch` (where the
calibrated network still misses), :mod:`.diagnose` (which mechanism it leaves out: ``thermodrift diagnose``).
"""

from thermodrift.core.physics import scenarios
from thermodrift.core.physics.integrate import CompiledNetwork, SimulationResult, simulate
from thermodrift.core.physics.mechanisms import Mechanism, Parameter
from thermodrift.core.physics.network import (Advection, AxisDriveSource, BearingSource, CuttingSource, Edge,
                                              MotorSource, Network, Node, Output, PreloadFeedback,
                                              radiation_conductance)
from thermodrift.core.physics.scenarios import Block, Scenario
from thermodrift.core.physics.sensors import DisplacementSensor, TemperatureSensor
from thermodrift.core.physics.spec import (apply_mechanism_list, load_network, network_from_dict, network_names,
                                           network_to_dict, schema)
from thermodrift.core.physics.synthetic import Synthetic, synthesize

__all__ = [
    "Advection", "AxisDriveSource", "BearingSource", "Block", "CompiledNetwork", "CuttingSource",
    "DisplacementSensor", "Edge", "Mechanism", "MotorSource", "Network", "Node", "Output", "Parameter",
    "PreloadFeedback", "Scenario", "SimulationResult", "Synthetic", "TemperatureSensor", "apply_mechanism_list",
    "load_network", "network_from_dict", "network_names", "network_to_dict", "radiation_conductance", "scenarios",
    "schema", "simulate", "synthesize",
]
