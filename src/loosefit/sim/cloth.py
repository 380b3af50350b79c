"""The names ``loosefit.cli`` imports from here, kept at this path while it moves to
their homes: :class:`~loosefit.sim.cloth_config.ClothConfig` and
:func:`~loosefit.sim.driver.simulate`. Everything else imports from those modules."""

from loosefit.sim.cloth_config import ClothConfig
from loosefit.sim.driver import simulate

__all__ = ["ClothConfig", "simulate"]
