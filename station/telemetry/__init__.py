"""The CCSDS framing of the downlink: Reed–Solomon (255,223), CRC, randomisation, DPCM
compression of the HRV lines."""
