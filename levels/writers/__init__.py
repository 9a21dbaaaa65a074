"""Writers of formats other tools read: DIMAP v1 1A scenes (``dimap``), SAR frames in the
house file (``sar``) and in ESA's ENVISAT format (``envisat``)."""
