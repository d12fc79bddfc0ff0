#!/usr/bin/env python3
"""Fault matrix: `lode run` outside its designed paths, one row per case.

Each case runs the real `lode` binary on a shipped pipeline edited for the case, and checks
what a lab needs of it: the fault detected within a stated number of cycles, the outputs
driven safe where the stage is at risk, an event saying what happened, and the recording
readable with everything up to its last flush (at most record.flush_interval_s = 1 s lost).
The table is printed at the end; the test fails if any row does.

    fault_matrix_test.py LODE SOURCE_DIR [CASE ...]

Hermetic: a private temporary folder and XDG_RUNTIME_DIR, telemetry off (no DDS domain), the
disk-full cases in a private mount namespace (unshare -m) with their own small tmpfs.
"""
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np

LODE, SRC = sys.argv[1], sys.argv[2]
ONLY = sys.argv[3:]
TMP = tempfile.mkdtemp(prefix=f"lode-faults-{os.getpid()}-")
RUNTIME = os.path.join(TMP, "run")
os.makedirs(RUNTIME, mode=0o700)
ENV = dict(os.environ, XDG_RUNTIME_DIR=RUNTIME)
FLUSH_S = 1.0  # record.flush_interval_s, the default


class CaseFailed(Exception):
    pass


def expect(condition, what):
    if not condition:
        raise CaseFailed(what)


def pipeline(name, base, edit):
    """A copy of config/BASE with `edit` applied to its text (each edit must apply)."""
    with open(os.path.join(SRC, "config", base)) as f:
        text = f.read()
    for old, new in edit:
        if old not in text:
            raise RuntimeError(f"test bug: {old!r} not in {base}")
        text = text.replace(old, new, 1)
    path = os.path.join(TMP, name + ".yaml")
    with open(path, "w") as f:
        f.write(text)
    return path


def lode_run(config, *args, timeout=180, prefix=()):
    summary = os.path.join(TMP, os.path.basename(config) + ".summary.json")
    cmd = [*prefix, LODE, "run", config, "--quiet", "--no-telemetry", "--summary-json", summary, *args]
    p = subprocess.run(cmd, env=ENV, capture_output=True, text=True, timeout=timeout)
    out = p.stdout + p.stderr
    result = None
    if os.path.exists(summary):
        with open(summary) as f:
            result = json.load(f)
    return p.returncode, out, result


def events_of(summary, kind=None):
    return [e for e in (summary or {}).get("events", []) if kind is None or e["kind"] == kind]


def recorded(path, series="kf.pose"):
    """(cycles, values by element) of one recorded series, read with h5py as a user would."""
    with h5py.File(path, "r") as f:
        g = f["signals"][series]
        cycles = g["cycle"][:]
        values = {k: g[k][:] for k in g.keys() if k not in ("cycle", "stamp_ns", "captured_ns", "time_s")}
        events = [(int(c), k.decode() if isinstance(k, bytes) else k, t.decode() if isinstance(t, bytes) else t)
                  for c, k, t in zip(f["events"]["cycle"][:], f["events"]["kind"][:], f["events"]["text"][:])]
    return cycles, values, events


def fault_cycle(summary):
    """The index of the cycle that faulted (the fault event carries the count of cycles run,
    that cycle included)."""
    faults = events_of(summary, "fault")
    return faults[0]["cycle"] - 1 if faults else None


# ---- the cases ------------------------------------------------------------------------------
# Each returns a dict for the table: detected (cycles from the cause to the reaction, with
# its bound), safe, event, recording.

def sigkill_mid_recording():
    config = os.path.join(SRC, "config", "kawato_planar.yaml")
    h5 = os.path.join(TMP, "killed.h5")
    p = subprocess.Popen([LODE, "run", config, "--clock", "real", "--duration", "20", "--record", h5,
                          "--no-telemetry"], env=ENV, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                         bufsize=1)
    seen = 0
    deadline = time.monotonic() + 60
    try:
        # The status line carries the cycle count; kill once it says 3 s of cycles ran.
        for line in p.stdout:
            m = re.search(r"cycle (\d+)", line)
            if m:
                seen = int(m.group(1))
            if seen >= 2400 or time.monotonic() > deadline:
                break
        p.send_signal(signal.SIGKILL)
    finally:
        p.wait()
    expect(seen >= 2400, f"the run never reported 2400 cycles (last status: cycle {seen})")
    expect(p.returncode == -signal.SIGKILL, f"lode was not killed (exit {p.returncode})")
    cycles, _, _ = recorded(h5)
    expect(len(cycles) > 0, "the recording holds no cycle")
    lost_s = (seen - int(cycles[-1])) / 800.0
    # The status line lags the RT thread, so `seen` is at most the cycle at the kill: the true
    # loss is at most lost_s plus that lag (the status is printed every 0.1 s).
    expect(lost_s <= FLUSH_S + 0.25, f"{lost_s:.2f} s lost before the kill (flush every {FLUSH_S} s)")
    # The real clock skips the periods an overrun lost (overrun_policy: skip): increasing,
    # not necessarily consecutive.
    expect(np.all(np.diff(cycles) >= 1), "recorded cycles do not increase")
    return dict(detected="-", safe="n/a (SIGKILL; CAN watchdog elsewhere)", event="-",
                recording=f"h5py reads {len(cycles)} cycles, {max(lost_s, 0):.2f} s before the kill lost")


READBACK = r"""
import sys, h5py, numpy
try:
    with h5py.File(sys.argv[1], "r") as f:
        c = f["signals"]["kf.pose"]["cycle"][:]
        ok = bool(numpy.all(c == numpy.arange(len(c))))
        print(f"READBACK rows={len(c)} consecutive={ok}")
except Exception as e:
    print(f"READBACK error={type(e).__name__}: {e}")
"""


def disk_full(policy):
    def case():
        edit = [] if policy == "continue" else [("\nmonitor:", "\nrecord: { on_error: stop }\n\nmonitor:")]
        config = pipeline(f"diskfull_{policy}", "kawato_planar.yaml", edit)
        mount = os.path.join(TMP, f"small_{policy}")
        os.makedirs(mount)
        h5 = os.path.join(mount, "r.h5")
        readback = os.path.join(TMP, "readback.py")
        with open(readback, "w") as f:
            f.write(READBACK)
        # This pipeline records about 0.8 kB a cycle: 4 MB fill after about 4000 cycles (5 s of
        # stage time, 2.5 s of wall time at 2x real time), after two or three good flushes. The
        # file is read back with h5py inside the namespace, before its tmpfs goes away.
        script = (f"mount -t tmpfs -o size=4m tmpfs {mount} || exit 97; \"$@\"; rc=$?; "
                  f"{sys.executable} {readback} {h5}; exit $rc")
        rc, out, summary = lode_run(config, "--duration", "12", "--speed", "2", "--record", h5,
                                    prefix=("unshare", "-m", "sh", "-c", script, "sh"))
        expect(os.geteuid() == 0 or rc != 97, "needs root: unshare -m and mount a tmpfs")
        expect(0 <= rc < 128, f"lode crashed (exit {rc}):\n{out[-2000:]}")
        expect(summary is not None, f"no summary written (exit {rc}):\n{out[-2000:]}")
        recs = summary.get("recordings", [])
        expect(len(recs) == 1, f"recordings in the summary: {recs}")
        rec = recs[0]
        expect(rec.get("complete") is False and "error" in rec, f"the summary does not say the recording failed: {rec}")
        expect("No space left on device" in rec["error"], f"unclear error: {rec['error']}")
        expect(rec["cycles"] > 0 and rec["lost"] > 0, f"kept {rec['cycles']}, lost {rec['lost']}: expected both > 0")
        failed = [e for e in summary["events"] if "recording" in e["text"] and "failed" in e["text"]]
        expect(failed, "no event says the recording failed")
        m = re.search(r"READBACK rows=(\d+) consecutive=(\w+)", out)
        expect(m is not None, f"h5py could not read the file: {re.search('READBACK.*', out).group(0) if 'READBACK' in out else out[-500:]}")
        rows, consecutive = int(m.group(1)), m.group(2) == "True"
        expect(rows >= rec["cycles"] and consecutive, f"h5py reads {rows} rows (consecutive: {consecutive}), "
               f"the summary says {rec['cycles']} were kept")
        if policy == "continue":
            expect(rc == 0, f"exit {rc}, expected 0 (the run goes on):\n{out[-1500:]}")
            expect(summary["result"] == "completed", f"result {summary['result']}")
            safe = "n/a (the loop went on)"
        else:
            expect(rc == 1, f"exit {rc}, expected 1 (record.on_error: stop):\n{out[-1500:]}")
            expect(fault_cycle(summary) is not None, "no fault event")
            safe = "driven safe (fault)"
        # The recorder flushes every second of wall time: at 2x real time that is 1600 cycles.
        lag = failed[0]["cycle"] - rec["cycles"]
        expect(lag <= 2 * 1600 + 1024, f"the failure was reported {lag} cycles after the last good flush")
        return dict(detected=f"{lag} cycles after the last good flush (<= 2 flushes)", safe=safe,
                    event=failed[0]["kind"],
                    recording=f"summary: {rec['cycles']} kept, {rec['lost']} lost; h5py reads {rows}")
    return case


def nan_without_fallback():
    config = pipeline("nan_nofallback", "kawato_planar.yaml",
                      [("    seed: 1\n", "    seed: 1\n    inject_nan: { channel: a1, start_s: 1.0, duration_s: 0.5 }\n")])
    h5 = os.path.join(TMP, "nan_nofallback.h5")
    rc, out, summary = lode_run(config, "--record", h5)
    expect(rc == 1, f"exit {rc}, expected 1:\n{out[-1500:]}")
    at = fault_cycle(summary)
    expect(at == 800, f"fault in cycle {at}, expected 800 (the first NaN sample)")
    fault = events_of(summary, "fault")[0]["text"]
    expect("outputs driven safe" in fault, fault)
    cycles, _, events = recorded(h5)
    expect(any(k == "fault" for _, k, _ in events), "the fault is not in the recording")
    expect(int(cycles[-1]) >= 799, f"the recording ends at cycle {cycles[-1]}")
    return dict(detected=f"{at - 800} cycles (0: same cycle)", safe="driven safe", event="fault",
                recording=f"to cycle {cycles[-1]}, fault event in /events")


SWAP_BASE = "kawato_planar_swap.yaml"  # 5 kHz, kf with the fallback kf_coast


def swap_run_with(name, injection, duration_s):
    """kawato_planar_swap with one io.sim injection (YAML text), recorded: (rc, out, summary, h5)."""
    config = pipeline(name, SWAP_BASE, [("    seed: 1\n", "    seed: 1\n    " + injection + "\n")])
    h5 = os.path.join(TMP, name + ".h5")
    rc, out, summary = lode_run(config, "--duration", str(duration_s), "--record", h5)
    return rc, out, summary, h5


def max_abs_truth_x(h5, from_cycle=0):
    """max |x| of the simulated truth from `from_cycle` on, and the number of cycles recorded."""
    cycles, values, _ = recorded(h5, "stage.truth")
    return float(np.max(np.abs(values["x"][cycles >= from_cycle]))), len(cycles)


def nan_with_fallback():
    rc, out, summary, h5 = swap_run_with("nan_fallback", "inject_nan: { channel: a1, start_s: 1.0, duration_s: 0.01 }", 2)
    expect(rc == 0, f"exit {rc}, expected 0 (the fallback takes over):\n{out[-1500:]}")
    trips = [e for e in summary["events"] if e["kind"] == "health"]
    expect(trips, "no health event")
    at = trips[0]["cycle"]
    expect(5000 <= at <= 5001, f"trip at cycle {at}, expected 5000")
    expect("kf_coast" in trips[0]["text"], trips[0]["text"])
    drift, cycles = max_abs_truth_x(h5, 5000)
    # The sine reference is 50 um; 50 cycles of coasting at 5 kHz must not add more than 10 um.
    expect(drift < 60e-6, f"|x| reached {drift * 1e6:.1f} um after the trip")
    return dict(detected=f"{at - 5000} cycles (same cycle)", safe="n/a (fallback took over)", event="health",
                recording=f"{cycles} cycles, max |x| {drift * 1e6:.1f} um after the trip")


def fallback_coasting_away():
    rc, out, summary, h5 = swap_run_with("coast_away", "inject_nan: { channel: a1, start_s: 1.0, duration_s: 5.0 }", 6)
    expect(rc == 1, f"exit {rc}, expected 1 (the envelope bounds the coast):\n{out[-1500:]}")
    at = fault_cycle(summary)
    fault = events_of(summary, "fault")[0]["text"]
    expect("envelope: glsdc.pose has been invalid" in fault, fault)
    # max_invalid_s: 0.05 at 5 kHz = 250 cycles of coasting allowed; the fault is at the 251st.
    expect(at is not None and at - 5000 <= 251, f"fault at cycle {at}, more than 251 cycles after the NaN")
    drift, _ = max_abs_truth_x(h5, 5000)
    expect(drift < 100e-6, f"the stage drifted {drift * 1e6:.1f} um before the fault")
    return dict(detected=f"{at - 5000} cycles (<= 251 = max_invalid_s)", safe="driven safe", event="fault (envelope)",
                recording=f"max |x| {drift * 1e6:.1f} um before the fault")


def stuck_sensor():
    rc, out, summary, h5 = swap_run_with(
        "stuck", "inject_stuck: { channel: a1, start_s: 1.0, duration_s: 2.0, value_v: 0.0 }", 2)
    trips = [e for e in summary["events"] if e["kind"] == "health"]
    expect(trips, f"no health trip (exit {rc}):\n{out[-1500:]}")
    at = trips[0]["cycle"]
    # The innovation test averages NIS over nis_window = 500 cycles: a stuck channel is caught
    # within that window.
    expect(5000 <= at <= 5500, f"trip at cycle {at}, outside the 500-cycle NIS window after the fault")
    worst, _ = max_abs_truth_x(h5)
    expect(worst < 0.080, f"the stage left its travel: |x| = {worst:.3f} m")
    fault = fault_cycle(summary)
    return dict(detected=f"{at - 5000} cycles (<= 500, NIS window)",
                safe="driven safe" if fault is not None else "n/a (inside the envelope)",
                event="health" + (" + fault" if fault is not None else ""),
                recording=f"max |x| {worst * 1e6:.0f} um")


def rss_kb(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


def command_flood():
    config = pipeline("flood", "kawato_planar.yaml", [("pipeline: kawato_planar", "pipeline: flood")])
    summary_path = os.path.join(TMP, "flood.summary.json")
    p = subprocess.Popen([LODE, "run", config, "--quiet", "--no-telemetry", "--duration", "3000", "--speed", "100",
                          "--summary-json", summary_path], env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    sock_path = os.path.join(RUNTIME, "lode", "flood.sock")
    try:
        for _ in range(200):
            if os.path.exists(sock_path):
                break
            time.sleep(0.05)
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.connect(sock_path)
        s.settimeout(30)
        reader = s.makefile("r")
        time.sleep(0.5)
        rss_before = rss_kb(p.pid)
        value = "x" * 60000
        replies = 0
        for i in range(2000):
            # A real runtime parameter with a value that is not a number: refused, and each
            # refusal is an event carrying the value (which is what used to pile up).
            s.sendall((json.dumps({"id": i, "kind": "set", "block": "stage", "name": "inject_nan_channel",
                                   "value": value}) + "\n").encode())
            reply = json.loads(reader.readline())
            expect(reply.get("id") == i and reply.get("ok") is False, f"reply {i}: {str(reply)[:200]}")
            replies += 1
        rss_after = rss_kb(p.pid)
        s.close()
    finally:
        p.send_signal(signal.SIGTERM)
        p.wait(timeout=60)
    with open(summary_path) as f:
        text = f.read()
    summary = json.loads(text)
    growth_mb = (rss_after - rss_before) / 1024.0
    # Before the caps each refused set kept its 60 KB value twice (event + summary): 125 MB.
    # Now each event text is at most 1 KiB and the log keeps 4352 events.
    expect(growth_mb < 16, f"RSS grew {growth_mb:.1f} MB over 2000 refused sets")
    expect(len(text) < 8e6, f"summary of {len(text) / 1e6:.1f} MB")
    refused = summary["events_suppressed"] + sum(1 for e in summary["events"] if e["kind"] == "command_failed")
    expect(refused >= 2000, f"{refused} refused sets accounted for (events + suppressed), expected 2000")
    return dict(detected=f"{replies}/2000 replied", safe="n/a",
                event=f"{summary['events_posted']} posted, {summary['events_suppressed']} suppressed (counted)",
                recording=f"RSS +{growth_mb:.1f} MB, summary {len(text) / 1e6:.2f} MB")


def replay_disk_full():
    """`lode replay` whose own file cannot be written: said so, the file removed, exit 1."""
    config = os.path.join(SRC, "config", "kawato_planar.yaml")
    recording = os.path.join(TMP, "replay_source.h5")
    rc, out, _ = lode_run(config, "--duration", "5", "--record", recording)
    expect(rc == 0, f"recording run exit {rc}:\n{out[-1000:]}")
    mount = os.path.join(TMP, "small_replay")
    os.makedirs(mount)
    output = os.path.join(mount, "replayed.h5")
    # The 5 s recording is about 3.3 MB; the replay's file of the same size fills 1 MB.
    script = f"mount -t tmpfs -o size=1m tmpfs {mount} || exit 97; \"$@\"; rc=$?; echo \"LEFT: $(ls {mount})\"; exit $rc"
    p = subprocess.run(["unshare", "-m", "sh", "-c", script, "sh", LODE, "replay", recording, "--quiet",
                        "--output", output], env=ENV, capture_output=True, text=True, timeout=120)
    text = p.stdout + p.stderr
    expect(os.geteuid() == 0 or p.returncode != 97, "needs root: unshare -m and mount a tmpfs")
    expect(p.returncode == 1, f"replay exit {p.returncode}, expected 1:\n{text[-1500:]}")
    expect("could not be written" in text and "No space left on device" in text,
           f"the replay does not say its file could not be written:\n{text[-1500:]}")
    expect("LEFT:" in p.stdout and "LEFT: replayed.h5" not in p.stdout,
           f"the unreadable file was left:\n{p.stdout[-500:]}")
    expect("cannot compare" not in text, f"a comparison with the unwritten file was attempted:\n{text[-1500:]}")
    return dict(detected="at close", safe="n/a", event="the replay's file could not be written",
                recording="removed (unreadable), exit 1")


def corrupted_recording():
    config = os.path.join(SRC, "config", "kawato_planar.yaml")
    good = os.path.join(TMP, "good.h5")
    rc, out, _ = lode_run(config, "--duration", "1", "--record", good)
    expect(rc == 0, f"recording run exit {rc}:\n{out[-1000:]}")
    size = os.path.getsize(good)
    rows = []
    for name, mangle in [("truncated", lambda b: b[: len(b) // 2]),
                         ("bytes flipped", lambda b: b[: len(b) // 2] + bytes(x ^ 0xFF for x in b[len(b) // 2: len(b) // 2 + 4096]) + b[len(b) // 2 + 4096:]),
                         ("zeroed header", lambda b: bytes(512) + b[512:]),
                         # the first object of the first global heap (its variable-length
                         # strings) stated as 1 MiB: HDF5 1.10 copies that much and crashes
                         ("heap object size", lambda b: b[: b.find(b"GCOL") + 24] + (1 << 20).to_bytes(8, "little")
                          + b[b.find(b"GCOL") + 32:])]:
        bad = os.path.join(TMP, f"bad_{len(rows)}.h5")
        with open(good, "rb") as f:
            data = f.read()
        with open(bad, "wb") as f:
            f.write(mangle(data))
        codes = []
        commands = [["replay", bad, "--quiet"]]
        if name != "bytes flipped":  # flipped values plot as values: only the replay's check can tell
            commands.append(["plot", bad, "--quiet", "-o", bad + ".html"])
        for command in commands:
            p = subprocess.run([LODE] + command, env=ENV, capture_output=True, text=True, timeout=120)
            expect(0 < p.returncode < 128,
                   f"{name}: {command[0]} exit {p.returncode} (expected an error, not success or a crash):\n"
                   f"{(p.stdout + p.stderr)[-800:]}")
            expect(bad in p.stdout + p.stderr,
                   f"{name}: {command[0]}'s error does not name the file:\n{(p.stdout + p.stderr)[-800:]}")
            codes.append(f"{command[0]} {p.returncode}")
        rows.append(f"{name}: exit " + ", ".join(codes))
    return dict(detected="on read", safe="n/a", event="error naming the file", recording="; ".join(rows))


CASES = [
    ("sigkill_mid_recording", sigkill_mid_recording),
    ("disk_full_continue", disk_full("continue")),
    ("disk_full_stop", disk_full("stop")),
    ("nan_without_fallback", nan_without_fallback),
    ("nan_with_fallback", nan_with_fallback),
    ("fallback_coasting_away", fallback_coasting_away),
    ("stuck_sensor", stuck_sensor),
    ("command_flood", command_flood),
    ("corrupted_recording", corrupted_recording),
    ("replay_disk_full", replay_disk_full),
]


def main():
    rows, failed = [], 0
    try:
        for name, case in CASES:
            if ONLY and name not in ONLY:
                continue
            start = time.monotonic()
            try:
                row = case()
                row["result"] = "ok"
            except CaseFailed as e:
                row = dict(detected="", safe="", event="", recording="", result=f"FAIL: {e}")
                failed += 1
            except Exception as e:  # a broken case is a failure too, with its reason
                row = dict(detected="", safe="", event="", recording="", result=f"FAIL: {type(e).__name__}: {e}")
                failed += 1
            row["case"] = name
            row["seconds"] = f"{time.monotonic() - start:.1f}"
            rows.append(row)
            print(f"{name}: {row['result']}", flush=True)
    finally:
        shutil.rmtree(TMP, ignore_errors=True)
    columns = ["case", "detected", "safe", "event", "recording", "seconds", "result"]
    widths = {c: max(len(c), *(len(str(r[c])) for r in rows)) for c in columns}
    print()
    print(" | ".join(c.ljust(widths[c]) for c in columns))
    print("-|-".join("-" * widths[c] for c in columns))
    for r in rows:
        print(" | ".join(str(r[c]).ljust(widths[c]) for c in columns))
    print(f"\n{len(rows) - failed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
