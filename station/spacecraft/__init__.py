"""The emulator: the orbit and its passes, the attitude, the HRV and ERS-1 SAR instruments,
the world (terrain, reflectance, SRTM tiles), imaging, the reference ortho-image, the
downlink's packets and frames. From ``levels`` it takes only checked primitives."""
