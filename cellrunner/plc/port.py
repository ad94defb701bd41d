"""Re-export of :mod:`cellrunner.model.cellport`, the contract between the engine and the
PLC servers (it lives in ``model`` so that both import it inward)."""

from cellrunner.model.cellport import *  # noqa: F403
from cellrunner.model.cellport import __all__ as __all__
