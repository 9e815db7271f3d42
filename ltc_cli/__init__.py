"""ltc: long-term consistent object-oriented semantic maps (LTC-Mapping, Sensors 2022)."""

__version__ = "0.1.0"

from ltc_cli.hookspecs import hookimpl  # noqa: E402  (plugins write @ltc_cli.hookimpl)

__all__ = ["hookimpl", "__version__"]
