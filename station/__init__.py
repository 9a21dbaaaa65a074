"""The emulated SPOT direct-receiving station: spacecraft, SRRS, SIPC, capacity model, CLI.

``station`` drives ``levels``; the reverse import is forbidden. What it holds:

- ``spacecraft``: the emulator (orbit, attitude, HRV and ERS-1 SAR, the world, the
  downlink's packets and frames); ``chain``, ``telemetry``: the channel and the CCSDS
  framing; ``srrs``: the receiving station (bytes to the L0 archive);
- ``truth``: what each product is held to (``truth.measure``: the one measure of a
  request of ``levels.work``);
- ``flow``: the one run skeleton; ``run``, ``run_sar``, ``processing``, ``campaign``: its
  flows (``station run``, ``station process``, a campaign); ``reprocess``: recorded
  archives and scenarios as requests of ``levels.work``;
- ``scenario``, ``sar_scenario``, ``loader``: the scenarios; ``preflight``, ``outdir``:
  what a run needs, checked before work, and its output directory;
- ``products``, ``locate``, ``refgcps``, ``compare``, ``catalog``, ``tables``,
  ``reports``: what the station does with products, real metadata, runs and reports;
- ``capacity``: the simpy model of the station; ``cli``: parse, call, print.
"""

__all__ = ["__version__"]

__version__ = "0.1.0"
