#!/usr/bin/env python3
"""Reads lodestone recordings with h5py and numpy only (no lodestone), as a user would.

Usage: read_recording.py CLOSED.h5 CRASHED.h5
Both files are written by hdf5_recorder_test (WritesFilesForPython): CLOSED.h5 by a writer
that closed the file, CRASHED.h5 by one that _exit()ed after flush() without closing. The
content is described next to write_known_rows() in hdf5_recorder_test.cpp:
  /signals/glsdc.pose  x = cycle*1e-3 [m], y = -cycle [m], θ = sin(cycle*1e-3) [rad], NaN every 1000th cycle
  /signals/plant.gap   gap [m], decimation 10
Exits 1 with a message naming the file and the check that failed.
"""
import sys

import h5py
import numpy as np

FLUSHED_CYCLES = 10_000


class CheckFailed(Exception):
    pass


def check(condition, message):
    if not condition:
        raise CheckFailed(message)


def as_str(value):
    """h5py 3.7 returns variable-length UTF-8 attributes as str, dataset elements as bytes."""
    return value.decode("utf-8") if isinstance(value, bytes) else str(value)


def check_file(path, closed):
    with h5py.File(path, "r") as f:
        check(as_str(f.attrs["format"]) == "lodestone-recording", "root attribute format")
        check(int(f.attrs["format_version"]) == 1, "root attribute format_version")
        check(as_str(f.attrs["source"]) == "lode run", "root attribute source")
        check(as_str(f.attrs["pipeline"]) == "kawato_planar", "root attribute pipeline")
        check(float(f.attrs["base_rate_hz"]) == 1000.0, "root attribute base_rate_hz")
        check(sorted(f["signals"].keys()) == ["glsdc.pose", "plant.gap"],
              f"series are {sorted(f['signals'].keys())}")

        pose = f["signals/glsdc.pose"]
        names = [as_str(n) for n in pose.attrs["names"]]
        units = [as_str(u) for u in pose.attrs["units"]]
        check(names == ["x", "y", "θ"], f"glsdc.pose names are {names}")
        check(units == ["m", "m", "rad"], f"glsdc.pose units are {units}")
        check(as_str(pose.attrs["topic"]) == "lode/kawato_planar/glsdc/pose", "glsdc.pose topic")
        check(as_str(pose.attrs["kind"]) == "signal", "glsdc.pose kind")
        check(float(pose.attrs["rate_hz"]) == 1000.0, "glsdc.pose rate_hz")
        check(int(pose.attrs["decimation"]) == 1, "glsdc.pose decimation")
        check(as_str(pose["θ"].attrs["unit"]) == "rad", "unit attribute of glsdc.pose/θ")
        check(as_str(pose["x"].attrs["unit"]) == "m", "unit attribute of glsdc.pose/x")
        check(as_str(pose["time_s"].attrs["unit"]) == "s", "unit attribute of glsdc.pose/time_s")

        rows = pose["cycle"].shape[0]
        if closed:
            check(rows == FLUSHED_CYCLES, f"glsdc.pose has {rows} rows, expected {FLUSHED_CYCLES}")
            check(int(pose.attrs["samples"]) == FLUSHED_CYCLES, "glsdc.pose attribute samples")
        else:
            check(rows >= FLUSHED_CYCLES, f"glsdc.pose has {rows} rows: flushed samples were lost")
        for column in ["stamp_ns", "captured_ns", "time_s", "x", "y", "θ"]:
            check(pose[column].shape[0] == rows, f"glsdc.pose/{column} has {pose[column].shape[0]} rows, cycle has {rows}")
        check(int(pose.attrs["gaps"]) == 0, "glsdc.pose attribute gaps")

        cycle = pose["cycle"][:FLUSHED_CYCLES]
        check(cycle.dtype == np.uint64, f"cycle dtype is {cycle.dtype}")
        check(np.array_equal(cycle, np.arange(FLUSHED_CYCLES, dtype=np.uint64)), "glsdc.pose/cycle values")
        c = cycle.astype(np.float64)
        check(np.array_equal(pose["x"][:FLUSHED_CYCLES], c * 1e-3), "glsdc.pose/x values")
        check(np.array_equal(pose["y"][:FLUSHED_CYCLES], -c), "glsdc.pose/y values")
        theta = pose["θ"][:FLUSHED_CYCLES]
        nan_rows = np.flatnonzero(np.isnan(theta))
        check(np.array_equal(nan_rows, np.arange(0, FLUSHED_CYCLES, 1000)), f"NaN rows of θ are {nan_rows}")
        finite = ~np.isnan(theta)
        check(np.allclose(theta[finite], np.sin(c[finite] * 1e-3), rtol=0, atol=1e-15), "glsdc.pose/θ values")
        check(abs(pose["time_s"][1234] - 1.234) < 1e-12, f"time_s[1234] is {pose['time_s'][1234]}")
        check(pose["captured_ns"][7] - pose["stamp_ns"][7] == 42, "captured_ns - stamp_ns")

        gap = f["signals/plant.gap"]
        check([as_str(u) for u in gap.attrs["units"]] == ["m"], "plant.gap units")
        check(as_str(gap.attrs["kind"]) == "raw", "plant.gap kind")
        check(int(gap.attrs["decimation"]) == 10, "plant.gap decimation")
        check(gap["gap"].shape[0] >= FLUSHED_CYCLES // 10, f"plant.gap has {gap['gap'].shape[0]} rows")
        check(gap["cycle"][5] == 50, "plant.gap/cycle[5]")

        events = f["events"]
        kinds = [as_str(k) for k in events["kind"][:]]
        texts = [as_str(t) for t in events["text"][:]]
        check(kinds[:2] == ["start", "fault"], f"event kinds are {kinds}")
        check(texts[1] == "ADC timeout", f"event texts are {texts}")
        check(events["cycle"][1] == FLUSHED_CYCLES - 1, "events/cycle[1]")
        return rows, type(events["kind"][0]).__name__


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        return 2
    for path, closed in [(sys.argv[1], True), (sys.argv[2], False)]:
        try:
            rows, event_type = check_file(path, closed)
        except CheckFailed as failure:
            print(f"FAIL {path}: {failure}")
            return 1
        except (OSError, KeyError) as error:
            print(f"FAIL {path}: h5py could not read it: {error}")
            return 1
        state = "closed" if closed else "crashed after flush"
        print(f"OK {path} ({state}): glsdc.pose has {rows} rows, names/units/values as written; "
              f"h5py {h5py.__version__} returns event strings as {event_type}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
