# Shared by the scripts that run kawato_planar through io.vme_pentek and lode-vme-emu (source
# it after test_lib.sh, with LODE, EMU and SRC set): the board config with its window in $TMP,
# the emulator, and the DAC registers as the window holds them.
WINDOW=$TMP/window

# vme_config OUT [SED_ARGS...]: config/kawato_planar_vme.yaml with the window in $TMP and a
# generous conversion timeout (the emulator is a process sharing two loaded cores with the
# rest of ctest: it may be off the CPU for milliseconds; a board needs ~10 us), edited further
# by SED_ARGS.
vme_config() {
  local out=$1
  shift
  sed -e "s#device: /dev/shm/lode-vme-kawato#device: $WINDOW#" \
      -e "s/conversion_timeout_us: [0-9]*/conversion_timeout_us: 300000/" "$@" \
      "$SRC/config/kawato_planar_vme.yaml" >"$out"
}

# start_emulator [CONFIG]: lode-vme-emu on CONFIG ($TMP/vme.yaml) with the plant of
# kawato_planar.yaml, output in $TMP/emu.out; EMU_PID; returns once it serves.
start_emulator() {
  "$EMU" "${1:-$TMP/vme.yaml}" --sim "$SRC/config/kawato_planar.yaml" >"$TMP/emu.out" 2>&1 &
  EMU_PID=$!
  PIDS+=($EMU_PID)
  for _ in $(seq 1 100); do grep -q "serving" "$TMP/emu.out" && return 0; sleep 0.1; done
  bad "emulator did not start"; cat "$TMP/emu.out"; return 1
}

# DAC_DATA[i] and DAC_LOAD as the register window holds them now. Default map: DAC_DATA at
# 0x200 + 4i, DAC_LOAD at 0x014; dac_registers WINDOW DAC_DATA STRIDE DAC_LOAD for another.
dac_registers() {
  $PY - "${1:-$WINDOW}" "${2:-0x200}" "${3:-4}" "${4:-0x014}" <<'PY'
import sys, struct
w = open(sys.argv[1], "rb").read()
base, stride, load = (int(a, 0) for a in sys.argv[2:5])
u32 = lambda off: struct.unpack_from("<I", w, off)[0]
print("dac", " ".join("%d" % u32(base + stride * i) for i in range(3)), "load", u32(load))
PY
}
