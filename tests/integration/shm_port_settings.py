"""Prints the health-check settings that Fast DDS 2.9 stored in the shared-memory ports of one
DDS domain, one line per port: "PORT HEALTH_CHECK_MS WAKE_MS".

A port is the file /dev/shm/fastrtps_port<N>; its creator writes, among other fields,
the port number, the number of listeners, the health-check timeout and the period at which
an idle listener wakes to show it is alive (a third of the timeout), then the queue
capacity, as consecutive 32-bit words. A process that opens the port while its check fails
sleeps that period before it tries again. The words are found by their pattern, not by an
offset, so padding before them does not matter.

Only ports created (or written) at or after SINCE (seconds since the epoch) when it is given:
a port file outlives a process that died, and its settings are that process's.

--remove-stale DOMAIN removes the port files of DOMAIN that no process listens on (a listener
holds an flock on fastrtps_port<N>_el; a process that exits, even cleanly, may leave the port
file behind). Fast DDS 2.9 takes such a file over as it is, without writing it again, so its
times, and the settings in it, stay those of the process that made it: a test of what this
build writes removes them first. Only for a domain no other process uses (the tests' private
domains): a port being created is not yet locked.

usage: shm_port_settings.py DOMAIN [SINCE]
       shm_port_settings.py --remove-stale DOMAIN
"""
import fcntl
import glob
import os
import struct
import sys


def settings(path, port):
    with open(path, "rb") as f:
        data = f.read()
    key = struct.pack("<I", port)
    at = data.find(key)
    while at != -1:
        if at % 4 == 0 and at + 20 <= len(data):
            _, listeners, health_ms, wake_ms, capacity = struct.unpack_from("<5I", data, at)
            if listeners < 1024 and 0 < health_ms and wake_ms == health_ms // 3 and capacity > 0:
                return health_ms, wake_ms
        at = data.find(key, at + 1)
    return None


def domain_ports(domain):
    """(port, path) of every port file of DOMAIN in /dev/shm."""
    first, last = 7400 + 250 * domain, 7400 + 250 * (domain + 1)
    for path in sorted(glob.glob("/dev/shm/fastrtps_port*")):
        name = os.path.basename(path)[len("fastrtps_port"):]
        if name.isdigit() and first <= int(name) < last:
            yield int(name), path


def remove_stale(domain):
    for port, path in domain_ports(domain):
        lock = path + "_el"
        try:
            fd = os.open(lock, os.O_RDWR)
        except FileNotFoundError:
            fd = None
        try:
            if fd is not None:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    continue  # a listener holds it
            for stale in (path, lock):
                try:
                    os.unlink(stale)
                    print("removed", stale)
                except FileNotFoundError:
                    pass
        finally:
            if fd is not None:
                os.close(fd)


def main():
    if sys.argv[1] == "--remove-stale":
        remove_stale(int(sys.argv[2]))
        return
    domain = int(sys.argv[1])
    since = float(sys.argv[2]) if len(sys.argv) > 2 else 0.0
    for port, path in domain_ports(domain):
        name = str(port)
        status = os.stat(path)
        if max(status.st_mtime, status.st_ctime) < since:
            continue
        found = settings(path, int(name))
        print(name, *(found if found else ("unknown", "unknown")))


main()
