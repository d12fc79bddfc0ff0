#!/usr/bin/env python3
"""`lode run` as a systemd service, without systemd: this test plays the service manager.

A unix datagram socket in a private folder is NOTIFY_SOCKET; WATCHDOG_USEC asks for a ping a
second; a file is the journal's stream (JOURNAL_STREAM = its device:inode, as systemd sets it).

1. watchdog: a pipeline with test.freezes_on_cue on the real clock. READY=1 arrives, and only
   once the start line (written after activation) is out; WATCHDOG=1 arrives again and again;
   `lode set freezer.freeze 1` (local socket) sticks the RT loop inside step(): the pings stop
   for several watchdog intervals while STATUS keeps coming (the process is alive, only the loop
   is stuck) and lode says so on a <3> line; SIGABRT, as systemd's WatchdogSignal, makes the
   crash guard drive the outputs safe and the process die of SIGABRT.
2. stop: the same pipeline without the freeze, stopped with SIGTERM as `systemctl stop` does:
   STOPPING=1, a final STATUS saying the outputs were driven safe, exit 0; every line of its
   output (stdout and stderr: one stream, as under systemd) carries a <N> priority, no status line.
3. fault: a pipeline whose envelope trips: exit 1, the fault on <3> lines, STOPPING=1.
4. not the journal (JOURNAL_STREAM names another file): no <N> prefix anywhere.

usage: service_notify_test.py LODE TEST_PLUGIN_DIR
"""
import os
import re
import resource
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

LODE, PLUGIN_DIR = sys.argv[1], sys.argv[2]
WATCHDOG_S = 1.0
failures = []


def ok(label):
    print(f"ok: {label}")


def bad(label, detail=""):
    print(f"FAIL: {label}" + (f"\n    {detail}" if detail else ""))
    failures.append(label)


def check(label, condition, detail=""):
    ok(label) if condition else bad(label, detail)


# The RT thread pinned to the last CPU we may use (when there are two or more): lode's
# other threads must keep off it.
ALLOWED_CPUS = sorted(os.sched_getaffinity(0))
RT_CPU = ALLOWED_CPUS[-1] if len(ALLOWED_CPUS) > 1 else None
PIPELINE = """\
pipeline: service_probe
rate_hz: 500
duration_s: 2
""" + (f"realtime: {{ cpu: {RT_CPU} }}\n" if RT_CPU is not None else "") + """\
blocks:
  ref:
    plugin: source.step
    names: [x]
    units: [m]
    steps: [{ time_s: 0.1, value: [1.0e-6] }]
  freezer:
    plugin: test.freezes_on_cue
    inputs: { in: ref.out }
"""
# The step at 0.1 s leaves the envelope: a fault.
FAULTING = PIPELINE.replace("duration_s: 2", "duration_s: 5") + """
envelope:
  freezer.out: { max_abs: [0.5e-6] }
"""


class Manager:
    """The notify socket, and every datagram with the time it arrived. On READY=1 it reads the
    run's log at once: what lode had written before saying it was ready."""

    def __init__(self, path, log_path):
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(path)
        self.sock.settimeout(0.2)
        self.log_path = log_path
        self.messages = []  # (time, [fields])
        self.log_at_ready = None
        self.lock = threading.Lock()
        self.running = True
        self.thread = threading.Thread(target=self.listen, daemon=True)
        self.thread.start()

    def listen(self):
        while self.running:
            try:
                data = self.sock.recv(4096)
            except socket.timeout:
                continue
            fields = data.decode(errors="replace").split("\n")
            if "READY=1" in fields and self.log_at_ready is None:
                with open(self.log_path, errors="replace") as f:
                    self.log_at_ready = f.read()
            with self.lock:
                self.messages.append((time.monotonic(), fields))

    def times(self, field, since=0.0):
        with self.lock:
            return [t for t, fs in self.messages if field in fs and t >= since]

    def statuses(self, since=0.0):
        with self.lock:
            return [f[7:] for t, fs in self.messages if t >= since for f in fs if f.startswith("STATUS=")]

    def wait_for(self, field, count=1, timeout=30.0, since=0.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if len(self.times(field, since)) >= count:
                return True
            time.sleep(0.05)
        return False

    def close(self):
        self.running = False
        self.thread.join()
        self.sock.close()


def no_core_dump():
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))


def start(tmp, name, config_text, extra_env, same_stream=True, journal=True, extra_args=()):
    """lode run CONFIG with its stderr (and stdout, when same_stream) in TMP/NAME.log."""
    config = os.path.join(tmp, name + ".yaml")
    with open(config, "w") as f:
        f.write(config_text)
    log_path = os.path.join(tmp, name + ".log")
    log = open(log_path, "w")
    out = log if same_stream else open(os.path.join(tmp, name + ".out"), "w")
    st = os.fstat(log.fileno())
    env = dict(os.environ, **extra_env)
    if journal:
        env["JOURNAL_STREAM"] = f"{st.st_dev}:{st.st_ino}"
    else:  # under systemd, but this stream was redirected elsewhere
        other = os.stat(tmp)
        env["JOURNAL_STREAM"] = f"{other.st_dev}:{other.st_ino}"
    proc = subprocess.Popen([LODE, "run", config, "--clock", "real", "--no-telemetry"] + list(extra_args), stdout=out, stderr=log,
                            env=env, preexec_fn=no_core_dump)
    return proc, log_path


def start_supervised(tmp, name, config_text, env, watchdog_s=None, extra_args=()):
    """start() under a stand-in service manager listening on TMP/NAME.sock as NOTIFY_SOCKET (and
    WATCHDOG_USEC when watchdog_s is given); returns the process, the manager and the log."""
    log_path = os.path.join(tmp, name + ".log")
    manager = Manager(os.path.join(tmp, name + ".sock"), log_path)
    notify_env = dict(env, NOTIFY_SOCKET=manager.sock.getsockname())
    if watchdog_s is not None:
        notify_env["WATCHDOG_USEC"] = str(int(watchdog_s * 1e6))
    proc, _ = start(tmp, name, config_text, notify_env, extra_args=extra_args)
    return proc, manager, log_path


def ready(manager, log_path):
    """READY=1 arrived within a minute; a failure shows the run's log."""
    if manager.wait_for("READY=1", timeout=60):
        return True
    bad("READY=1 arrives", read(log_path)[-2000:])
    return False


def stop(proc):
    if proc.poll() is None:
        proc.kill()
        proc.wait()


def read(path):
    with open(path, errors="replace") as f:
        return f.read()


def cpu_list(text):
    cpus = set()
    for part in text.strip().split(","):
        lo, _, hi = part.partition("-")
        cpus.update(range(int(lo), int(hi or lo) + 1))
    return cpus


def thread_cpus(pid):
    """{thread id: (name, CPUs it may run on)} of a running process."""
    threads = {}
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            name = read(f"/proc/{pid}/task/{tid}/comm").strip()
            status = read(f"/proc/{pid}/task/{tid}/status")
        except OSError:
            continue  # the thread ended meanwhile
        m = re.search(r"^Cpus_allowed_list:\s*(\S+)", status, re.M)
        if m:
            threads[tid] = (name, cpu_list(m.group(1)))
    return threads


def lode_set(env, what):
    r = subprocess.run([LODE, "set", "--local", "--pipeline", "service_probe", "--timeout", "5"] + what, env=env,
                       capture_output=True, text=True, timeout=30)
    return r.returncode, r.stdout + r.stderr


def watchdog_case(tmp, env):
    print("--- 1. a frozen loop stops the watchdog pings; SIGABRT drives the outputs safe")
    proc, manager, log_path = start_supervised(tmp, "watchdog", PIPELINE, env, WATCHDOG_S, ["--until-stopped"])
    try:
        if not ready(manager, log_path):
            return
        ok("READY=1 arrives")
        before = manager.log_at_ready or ""
        check("READY=1 only after the start line (the pipeline is active)",
              re.search(r"^<6>lode: started pipeline 'service_probe'", before, re.M), f"log at READY: {before!r}")
        ready_at = manager.times("READY=1")[0]
        check("STATUS with READY=1 gives cycle, rate, overruns, faults",
              any(re.match(r"cycle \d+, [\d.]+ Hz, overruns \d+, faults 0$", s) for s in manager.statuses()),
              str(manager.statuses()[:3]))
        pings = manager.wait_for("WATCHDOG=1", count=4, timeout=20, since=ready_at + 0.01)
        check("WATCHDOG=1 arrives repeatedly while the loop runs", pings, f"{len(manager.times('WATCHDOG=1'))} pings")

        if RT_CPU is None:
            print("    (one CPU: no affinity to check)")
        else:
            threads = thread_cpus(proc.pid)
            rt = [cpus for name, cpus in threads.values() if name == "lode-rt"]
            others = {f"{name} ({tid})": sorted(cpus) for tid, (name, cpus) in threads.items() if name != "lode-rt"}
            check(f"the RT thread runs on cpu {RT_CPU} alone", rt == [{RT_CPU}], str(rt))
            check(f"lode's {len(others)} other threads keep off cpu {RT_CPU}",
                  others and all(RT_CPU not in cpus for cpus in others.values()), str(others))

        rc, reply = lode_set(env, ["freezer.freeze", "1"])
        frozen_at = time.monotonic()
        check("lode set freezer.freeze 1 is accepted", rc == 0, reply)
        print("    | " + reply.strip().replace("\n", "\n    | "))
        # One ping may still come from progress made before the freeze (pings every half interval).
        quiet_from = frozen_at + WATCHDOG_S
        time.sleep(WATCHDOG_S + 3 * WATCHDOG_S)
        late = manager.times("WATCHDOG=1", since=quiet_from)
        check(f"no WATCHDOG=1 for {3 * WATCHDOG_S:.0f} s once the loop is frozen", not late,
              f"{len(late)} pings after the freeze")
        check("the process is still alive (only the loop is stuck)", proc.poll() is None, f"exit {proc.poll()}")
        stalled = manager.statuses(since=quiet_from)
        check("STATUS keeps coming meanwhile (the non-real-time side runs) and says the loop makes no progress",
              len(stalled) >= 2 and all(s.startswith("NO PROGRESS: cycle ") for s in stalled), str(stalled))
        text = read(log_path)
        check("lode says the loop made no progress, as an error (<3>)",
              re.search(r"^<3>lode: the real-time loop has made no progress", text, re.M), text[-1500:])

        proc.send_signal(signal.SIGABRT)  # systemd's WatchdogSignal
        try:
            rc = proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            rc = None
        check("lode dies of SIGABRT", rc == -signal.SIGABRT, f"exit status {rc}")
        text = read(log_path)
        check("the crash guard drove the outputs safe, said on a <2> line naming the sender",
              re.search(r"^<2>lode: SIGABRT: sent by process \d+ .*outputs driven to their safe values$", text, re.M),
              text[-1500:])
    finally:
        stop(proc)
        manager.close()


def stop_case(tmp, env):
    print("--- 2. SIGTERM (systemctl stop) of a run --until-stopped: STOPPING=1, outputs driven safe, exit 0, "
          "<N> on every line")
    proc, manager, log_path = start_supervised(tmp, "stop", PIPELINE, env, WATCHDOG_S, ["--until-stopped"])
    try:
        if not ready(manager, log_path):
            return
        time.sleep(3.0)  # past duration_s (2 s): --until-stopped runs on
        check("--until-stopped outlives duration_s", proc.poll() is None, f"exit {proc.poll()}")
        proc.send_signal(signal.SIGTERM)
        try:
            rc = proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            rc = None
        check("exit 0 after SIGTERM", rc == 0, f"exit status {rc}\n{read(log_path)[-1500:]}")
        time.sleep(0.3)  # the last datagrams
        stopping = manager.times("STOPPING=1")
        check("STOPPING=1 sent, after READY=1", stopping and stopping[0] > manager.times("READY=1")[0],
              str(manager.messages[-5:]))
        final = manager.statuses()[-1] if manager.statuses() else ""
        check("the last STATUS says the run stopped and the outputs were driven safe",
              re.match(r"stopped by signal at cycle \d+ \(outputs driven safe\)$", final), final)
        text = read(log_path)
        lines = [l for l in text.split("\n") if l]
        unprefixed = [l for l in lines if not re.match(r"<[0-7]>", l)]
        check("every line carries a <N> priority", lines and not unprefixed, "\n    ".join(unprefixed[:5]))
        check("the start line is <6>", re.search(r"^<6>lode: started pipeline", text, re.M), text[:500])
        check("the summary says the outputs were driven safe (<5>)",
              re.search(r"^<5>  stopped by signal at cycle \d+ \(outputs driven safe\)$", text, re.M), text[-800:])
        check("the summary's figures are <6>", re.search(r"^<6>  timing: ", text, re.M), text[-800:])
        check("no status line under the journal", not re.search(r"^<\d>cycle \d+ ", text, re.M), text[-800:])
    finally:
        stop(proc)
        manager.close()


def fault_case(tmp, env):
    print("--- 3. a fault: exit 1, <3> lines, STOPPING=1")
    proc, manager, log_path = start_supervised(tmp, "fault", FAULTING, env)
    try:
        try:
            rc = proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            rc = None
        time.sleep(0.3)
        text = read(log_path)
        check("exit 1 on the fault", rc == 1, f"exit status {rc}\n{text[-1500:]}")
        check("the fault event is <3>", re.search(r"^<3>lode: fault: envelope: freezer\.out", text, re.M), text[-1500:])
        check("the summary's FAULT line is <3>", re.search(r"^<3>  FAULT: .*\(outputs driven safe\)$", text, re.M),
              text[-1500:])
        check("STOPPING=1 sent", manager.times("STOPPING=1"), str(manager.messages[-5:]))
        final = manager.statuses()[-1] if manager.statuses() else ""
        check("the last STATUS names the fault", final.startswith("fault: envelope:"), final)
    finally:
        stop(proc)
        manager.close()


def not_journal_case(tmp, env):
    print("--- 4. a stream that is not the journal: output unchanged (no <N>)")
    proc, log_path = start(tmp, "plain", FAULTING, env, journal=False)
    try:
        rc = proc.wait(timeout=60)
        text = read(log_path)
        check("the run faults as before", rc == 1, f"exit status {rc}")
        check("no <N> prefix on any line", not re.search(r"^<\d>", text, re.M), text[:800])
        check("the summary's FAULT line as before", re.search(r"^  FAULT: .*\(outputs driven safe\)$", text, re.M),
              text[-800:])
    finally:
        stop(proc)


def main():
    tmp = tempfile.mkdtemp(prefix="lode-service-")
    run_dir = os.path.join(tmp, "run")
    os.mkdir(run_dir, 0o700)
    env = {k: v for k, v in os.environ.items()
           if k not in ("NOTIFY_SOCKET", "WATCHDOG_USEC", "WATCHDOG_PID", "JOURNAL_STREAM")}
    env["XDG_RUNTIME_DIR"] = run_dir  # our own command sockets: no other run meets them
    env["LODE_PLUGIN_PATH"] = env.get("LODE_PLUGIN_PATH", "") + ":" + PLUGIN_DIR
    try:
        watchdog_case(tmp, env)
        stop_case(tmp, env)
        fault_case(tmp, env)
        not_journal_case(tmp, env)
    finally:
        subprocess.run(["rm", "-rf", tmp])
    if failures:
        print(f"FAILED: {len(failures)} check(s)")
        return 1
    print("PASS")
    return 0


if __name__ == "__main__":
    sys.exit(main())
