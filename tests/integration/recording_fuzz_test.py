#!/usr/bin/env python3
"""Damaged recordings never crash or hang `lode replay` and `lode plot`.

Records 0.2 s of kawato_planar, then makes COUNT damaged copies (a fixed seed, so a failure
is reproducible): bits flipped in the first 8 KiB (the superblock, object headers and the
global heap of the strings), bits flipped in the last 64 KiB, bytes overwritten anywhere,
a truncation, a zeroed 512-byte block. Each copy goes through `lode replay` and `lode plot`,
which must end on their own with 0, 1 or 2 (never a signal, never the timeout) and print
UTF-8 text. Before each file was read in a child process first, one copy in about 40 of
these crashed HDF5 (SIGSEGV in H5HG_read) and one in a few hundred hung it or made it clear
gigabytes.

usage: recording_fuzz_test.py LODE SOURCE_DIR [COUNT] [SEED]
"""
import collections
import os
import random
import shutil
import subprocess
import sys
import tempfile

LODE, SRC = sys.argv[1], sys.argv[2]
COUNT = int(sys.argv[3]) if len(sys.argv) > 3 else 120
SEED = int(sys.argv[4]) if len(sys.argv) > 4 else 1
TMP = tempfile.mkdtemp(prefix=f"lode-recording-fuzz-{os.getpid()}-")
ENV = dict(os.environ, XDG_RUNTIME_DIR=os.path.join(TMP, "run"))
os.makedirs(ENV["XDG_RUNTIME_DIR"], mode=0o700)


def damage(data, rnd):
    b = bytearray(data)
    kind = rnd.choice(["flip_head", "flip_head", "flip_tail", "overwrite", "truncate", "zero_block"])
    if kind == "flip_head":
        for _ in range(rnd.randint(1, 4)):
            b[rnd.randrange(0, min(len(b), 8192))] ^= 1 << rnd.randrange(8)
    elif kind == "flip_tail":
        for _ in range(rnd.randint(1, 4)):
            b[rnd.randrange(max(0, len(b) - 65536), len(b))] ^= 1 << rnd.randrange(8)
    elif kind == "overwrite":
        for _ in range(rnd.randint(1, 8)):
            b[rnd.randrange(len(b))] = rnd.randrange(256)
    elif kind == "truncate":
        b = b[: rnd.randrange(len(b))]
    else:
        at = rnd.randrange(len(b))
        b[at:at + 512] = bytes(len(b[at:at + 512]))
    return kind, bytes(b)


def main():
    good = os.path.join(TMP, "good.h5")
    run = subprocess.run([LODE, "run", os.path.join(SRC, "config", "kawato_planar.yaml"), "--duration", "0.2",
                          "--no-telemetry", "--no-local-control", "--quiet", "--record", good],
                         env=ENV, capture_output=True, timeout=120)
    if run.returncode != 0:
        print(f"FAIL: the recording run exited {run.returncode}:\n{run.stderr.decode(errors='replace')[-1500:]}")
        return 1
    data = open(good, "rb").read()
    rnd = random.Random(SEED)
    outcomes = collections.Counter()
    failures = []
    for i in range(COUNT):
        kind, damaged = damage(data, rnd)
        path = os.path.join(TMP, f"damaged_{i}.h5")
        with open(path, "wb") as f:
            f.write(damaged)
        for command in (["replay", path, "--quiet", "--output", os.path.join(TMP, "replayed.h5")],
                        ["plot", path, "--quiet", "-o", os.path.join(TMP, "report.html")]):
            try:
                p = subprocess.run([LODE] + command, env=ENV, capture_output=True, timeout=90)
                code = p.returncode
                text = p.stdout + p.stderr
            except subprocess.TimeoutExpired:
                code, text = "timeout", b""
            outcomes[(command[0], code)] += 1
            problem = None
            if code not in (0, 1, 2):
                problem = f"ended with {code}"
            else:
                try:
                    text.decode("utf-8")
                except UnicodeDecodeError as e:
                    problem = f"printed bytes that are not UTF-8 ({e})"
            if problem:
                keep = os.path.join(TMP, f"failed_{i}_{command[0]}.h5")
                shutil.copy(path, keep)
                failures.append(f"copy {i} ({kind}, seed {SEED}): lode {command[0]} {problem}\n"
                                f"    {text.decode(errors='replace')[-400:]}")
        os.remove(path)
    for (command, code), n in sorted(outcomes.items(), key=str):
        print(f"lode {command}: exit {code} x {n}")
    for f in failures:
        print("FAIL: " + f)
    if failures:
        print(f"{len(failures)} failures of {2 * COUNT} runs; the damaged copies are kept in {TMP}")
        return 1
    print(f"ok: {COUNT} damaged recordings, {2 * COUNT} runs, none crashed or hung")
    shutil.rmtree(TMP, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
