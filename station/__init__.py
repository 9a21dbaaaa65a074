"""The emulated SPOT direct-receiving station: spacecraft, SRRS, SIPC, capacity model, CLI.

``station`` drives ``levels``; the reverse import is forbidden.
"""

__all__ = ["__version__"]

__version__ = "0.1.0"
