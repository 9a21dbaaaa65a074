"""The receiving station (SRRS): frame sync, Reed–Solomon, virtual-channel demultiplexing,
the gap/duplicate/reorder accounting, the L0 archive; bytes in, bytes out."""
