#!/usr/bin/env python3
"""Checks a `lode record` file with h5py only (no lodestone): every signal series has the
expected number of samples for its rate, cycles contiguous, names and units present.
usage: check_recording.py FILE SAMPLES_AT_FULL_RATE"""
import sys

import h5py
import numpy as np

path, full = sys.argv[1], int(sys.argv[2])
ok = True
with h5py.File(path, "r") as f:
    assert f.attrs["format"] in (b"lodestone-recording", "lodestone-recording"), dict(f.attrs)
    for name, g in f["signals"].items():
        cycles = g["cycle"][:]
        dec = int(g.attrs["decimation"])
        expected = full // dec
        steps = np.diff(cycles.astype(np.int64))
        gaps = int(np.sum(steps != dec))
        names = [n.decode() if isinstance(n, bytes) else n for n in g.attrs["names"]]
        units = [u.decode() if isinstance(u, bytes) else u for u in g.attrs["units"]]
        first = names[0]
        unit = g[first].attrs["unit"]
        print(f"  {name}: {len(cycles)} samples (expected {expected}), {gaps} irregular steps, "
              f"{first} [{unit.decode() if isinstance(unit, bytes) else unit}] ...")
        if len(cycles) != expected or gaps or cycles[0] != 0 or len(names) != len(units):
            ok = False
sys.exit(0 if ok else 1)
