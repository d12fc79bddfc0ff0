"""A closed loop through a board and its emulator against the same pipeline through io.sim:
equal within quantization, or exit 1.

usage: compare_with_sim.py BOARD.h5 SIM.h5 LABEL

Within quantization means: the ADC samples at most one code apart (the same converter and the
same noise; the 16-bit DAC/RPDO codes quantize the forces, so the plant moves a little
differently and now and then a Hall sample lands one code away), and the estimates apart by
less than the single-sample noise of the GLSDC pose (what one code's flip moves it by is a
fraction of that)."""
import sys

import h5py
import numpy as np

board, sim, label = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r"), sys.argv[3]


def series(f, sig):
    g = f["signals/" + sig]
    return np.column_stack([g[n][:] for n in g.attrs["names"]])


n = min(len(series(board, "kf.pose")), len(series(sim, "kf.pose")))
assert n >= 2400, n
d = np.abs(series(board, "kf.pose")[:n] - series(sim, "kf.pose")[:n])
s = np.abs(series(board, "stage.signals")[:n] - series(sim, "stage.signals")[:n])
lsb = 20.0 / 65536
print("kf.pose max |%s - io.sim|: x %.3g m, y %.3g m, theta_z %.3g rad over %d cycles"
      % (label, d[:, 0].max(), d[:, 1].max(), d[:, 2].max(), n))
print("stage.signals max |%s - io.sim| %.3g V (%.2f LSB); samples that differ: %d of %d"
      % (label, s.max(), s.max() / lsb, int((s > 0).sum()), s.size))
print("forces: max |fx| %.3g N, |fy| %.3g N, |tz| %.3g N*m" % tuple(np.abs(series(board, "ctrl.out")[:n]).max(axis=0)))
noise = np.std(series(sim, "glsdc.pose")[:n] - series(sim, "stage.truth")[:n], axis=0)
print("GLSDC single-sample noise std (io.sim run): x %.3g m, y %.3g m, theta_z %.3g rad" % tuple(noise))
print("max difference / noise std: %.2f %.2f %.2f" % tuple(d.max(axis=0) / noise))
if not (d.max(axis=0) < noise).all() or s.max() > lsb + 1e-12:
    print("%s and io.sim differ beyond quantization" % label)
    sys.exit(1)
