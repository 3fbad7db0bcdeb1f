"""nlo_lab: kinematic motion retargeting by neural latent optimisation."""

__version__ = "0.1.0"
