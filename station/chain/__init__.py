"""The chain between the emulated spacecraft and the station: a pass sent through the
channel and received (``session``: emulate → transmit → impair → receive → record), the
downlink's report checked against what was sent (``report``), and hostile frame streams
for the receiver's fuzzing (``fuzzing``).

This is where the emulator (``station.spacecraft``) meets the receiving station
(``station.srrs``): the station itself never imports the emulator, as a real station only
ever sees bytes.
"""

__all__: list[str] = []
