"""The station live: a front end on a socket (:mod:`station.live.frontend`), the emulator's
sender at line rate (:mod:`station.live.sender`), and what travels between them
(:mod:`station.live.wire`)."""
