"""Built-in optimizer plugins, one module per method."""

from thermodrift.optimizers import PopulationSampler
from thermodrift.plugins.optimizers.fa import FASampler
from thermodrift.plugins.optimizers.gwo import GWOSampler
from thermodrift.plugins.optimizers.pso import ConstrictionPSOSampler, PSOSampler
from thermodrift.plugins.optimizers.rbmo import RBMOSampler
from thermodrift.plugins.optimizers.rbmox import RBMOXSampler

__all__ = ["ConstrictionPSOSampler", "FASampler", "GWOSampler", "PSOSampler", "PopulationSampler", "RBMOSampler",
           "RBMOXSampler"]
