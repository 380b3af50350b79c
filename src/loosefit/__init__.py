"""loosefit: loose-fitting garment animation via a generative model of deformation decomposition."""

__version__ = "0.1.0"
