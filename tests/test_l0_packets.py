"""Level 0 others read (issue 59 §6): ``station export L0.h5 --packets DIR`` writes the
archive's lines and auxiliary records as CCSDS space packets, one file per APID with its
packet definition, and ccsdspy (an outside reader) gives the archive back: every line's
counts, validity, counter and time, every auxiliary record, each packet's CRC as the
standard library's CRC-CCITT computes it."""

from __future__ import annotations

import binascii
import json
import logging
from pathlib import Path

import numpy as np

logging.getLogger("ccsdspy").setLevel(logging.WARNING)


def test_ccsdspy_reads_the_exported_packets_as_the_archive_holds_them(
    run_dir: Path, tmp_path: Path, capsys
) -> None:
    import ccsdspy
    import h5py

    from levels.readers.l0 import read_l0
    from station.cli import main

    l0 = run_dir / "small_test.l0.h5"
    assert main(["export", str(l0), "--packets", str(tmp_path)]) == 0
    assert "APID 256" in capsys.readouterr().out
    listing = json.loads((tmp_path / "packets.json").read_text())
    archive = read_l0(l0)
    by_apid = {f["apid"]: f for f in listing["files"]}
    assert set(by_apid) == {0x010, *(0x100 + k for k in range(len(archive.bands)))}

    def load(apid: int) -> dict:
        f = by_apid[apid]
        definition = ccsdspy.FixedLength.from_file(str(tmp_path / f["definition"]))
        return definition.load(str(tmp_path / f["file"]), include_primary_header=True)

    for k, (name, band) in enumerate(archive.bands.items()):
        got = load(0x100 + k)
        assert by_apid[0x100 + k]["packets"] == archive.n_lines == got["counts"].shape[0]
        assert np.array_equal(got["counts"], np.asarray(band.counts))
        assert np.array_equal(got["segment_valid"].astype(bool), band.valid)
        assert np.array_equal(got["line_counter"], archive.line_counter)
        assert np.array_equal(got["line_t_s"], archive.line_t_s)
        assert set(got["CCSDS_APID"]) == {0x100 + k} and set(got["CCSDS_SEQUENCE_FLAG"]) == {3}
        assert np.array_equal(got["CCSDS_SEQUENCE_COUNT"], np.arange(archive.n_lines) & 0x3FFF)
        # each packet's CRC, as the standard library computes CRC-CCITT (init 0xFFFF)
        raw = (tmp_path / by_apid[0x100 + k]["file"]).read_bytes()
        size = len(raw) // archive.n_lines
        for i in (0, archive.n_lines // 2, archive.n_lines - 1):
            packet = raw[i * size : (i + 1) * size]
            assert binascii.crc_hqx(packet[6:-2], 0xFFFF) == got["crc16"][i], (name, i)
    aux = load(0x010)
    with h5py.File(l0) as f:
        for key in ("time_ms", "line_time_ms", "line_counter", "mirror_step", "status"):
            assert np.array_equal(aux[key], f["aux"][key][()]), key
        assert np.array_equal(aux["gyro_rates_rad_per_s"], f["aux/gyro_rates_rad_per_s"][()])
    assert np.array_equal(aux["t_s"], archive.aux_t_s)
