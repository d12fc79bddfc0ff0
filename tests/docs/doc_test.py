#!/usr/bin/env python3
"""Runs the shell commands that README.md and docs/*.md show, so the documentation cannot rot.

Every fenced block whose info string starts with `sh` must say what happens to it:

    ```sh runnable            run by this test, in order with the file's other blocks
    ```sh runnable exit=2     run in a subshell; its last command must exit 2 (a refused
                              config). A `cd` or `export` inside it does not carry on.
    ```sh not-run: REASON     shown only (installs packages, needs a VME crate, ...)

A bare ```sh block is an error: a command nobody runs is a command that goes stale.

The runnable blocks of one file run in one bash process (`set -e -o pipefail`), so a `cd`,
an `export` or a background `lode run &` carries on to the next block, in a private scratch
directory laid out like the repository: each top-level entry is a symlink into the source
tree, `build` points at the build tree, and files the commands write land in the scratch
directory. Each file gets its own HOME, XDG_RUNTIME_DIR (local command sockets) and DDS
domain (LODE_DDS_DOMAIN, taken under the same lock files as the other tests), so it shares
nothing with another test or another user's run. Whatever a file left running is killed
when its blocks are done.

usage: doc_test.py --source DIR --build DIR [FILE.md ...]   (default: README.md docs/*.md)
"""
import argparse
import errno
import fcntl
import glob
import os
import re
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

FENCE = re.compile(r"^(?P<indent>\s*)(?P<fence>```+|~~~+)(?P<info>.*)$")
SHELL_LANGUAGES = {"sh", "bash", "shell", "console"}
FILE_TIMEOUT_S = 600


class Block:
    def __init__(self, path, line, info, text):
        self.path, self.line, self.info, self.text = path, line, info, text

    @property
    def where(self):
        return f"{self.path}:{self.line}"


def fenced_blocks(path, display):
    """Yields every fenced block of a Markdown file with the line its fence opens on."""
    lines = open(path, encoding="utf-8").read().split("\n")
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence, info = len(m["indent"]), m["fence"], m["info"].strip()
        body, j = [], i + 1
        while j < len(lines):
            close = FENCE.match(lines[j])
            if close and close["fence"].startswith(fence[:3]) and close["info"].strip() == "":
                break
            body.append(lines[j][indent:] if lines[j][:indent].strip() == "" else lines[j])
            j += 1
        yield Block(display, i + 1, info, "\n".join(body))
        i = j + 1


def classify(block):
    """Returns ('run', expected_exit), ('skip', reason), or ('error', message); None if not shell."""
    words = block.info.split(None, 1)
    if not words or words[0] not in SHELL_LANGUAGES:
        return None
    rest = words[1].strip() if len(words) > 1 else ""
    if rest.startswith("not-run:"):
        reason = rest[len("not-run:"):].strip()
        if len(reason) < 8:
            return ("error", "`not-run:` needs a reason (what the reader needs that a test cannot have)")
        return ("skip", reason)
    m = re.fullmatch(r"runnable(?:\s+exit=(\d+))?", rest)
    if m:
        return ("run", int(m[1] or 0))
    return ("error", f"shell block must be marked `{words[0]} runnable` or `{words[0]} not-run: REASON` "
                     f"(info string was {block.info!r})")


def take_private_domain(lock_dir="/tmp/lode-test-domains"):
    """A DDS domain id no other process on this host uses, held until this process exits.
    The same lock files and checks as the other tests (tests/integration/private_domain.sh)."""
    os.makedirs(lock_dir, exist_ok=True)
    try:
        os.chmod(lock_dir, 0o1777)
    except OSError:
        pass
    for i in range(130):
        domain = 100 + (os.getpid() + i) % 130
        try:
            fd = os.open(f"{lock_dir}/{domain}", os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o666)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue
        if domain_in_use(domain):
            os.close(fd)
            continue
        return domain, fd
    sys.exit("FAIL: no free DDS test domain in 100-229")


def domain_in_use(domain):
    for participant in range(8):
        port = 7400 + 250 * domain + 10 + 2 * participant
        if os.path.exists(f"/dev/shm/fastrtps_port{port}"):
            return True
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            s.bind(("0.0.0.0", port))
        except OSError as e:
            if e.errno == errno.EADDRINUSE:
                return True
        finally:
            s.close()
    return False


def scratch_tree(source, build, root):
    work = os.path.join(root, "work")
    os.makedirs(work)
    for entry in os.listdir(source):
        if entry in (".git", "build"):
            continue
        os.symlink(os.path.join(source, entry), os.path.join(work, entry))
    os.symlink(build, os.path.join(work, "build"))
    for d in ("home", "run"):
        os.makedirs(os.path.join(root, d), mode=0o700)
    return work


def script_for(blocks):
    """One bash script: each block announces where it comes from so a failure names it."""
    out = ["set -e -o pipefail",
           'trap \'echo "doc-test: FAILED in $DOC_BLOCK (exit $?, at: $BASH_COMMAND)" >&2\' ERR']
    for block, expected in blocks:
        out.append(f"DOC_BLOCK={shlex.quote(block.where)}")
        out.append('echo "doc-test: --- $DOC_BLOCK"')
        if expected == 0:
            out.append(block.text)
        else:
            out.append("set +e; trap - ERR")
            out.append("(\n" + block.text + "\n)")
            out.append(f'doc_rc=$?; set -e; if [ "$doc_rc" -ne {expected} ]; then '
                       f'echo "doc-test: FAILED in $DOC_BLOCK: exit $doc_rc, expected {expected}" >&2; exit 1; fi')
            out.append('trap \'echo "doc-test: FAILED in $DOC_BLOCK (exit $?, at: $BASH_COMMAND)" >&2\' ERR')
    out.append('echo "doc-test: --- done"')
    return "\n".join(out) + "\n"


def end_process_group(pgid, sig):
    try:
        os.killpg(pgid, sig)
    except ProcessLookupError:
        return
    for _ in range(100):
        time.sleep(0.1)
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return
    try:
        os.killpg(pgid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def run_file(display, blocks, source, build, domain):
    root = tempfile.mkdtemp(prefix="lode-doc-test-")
    try:
        work = scratch_tree(source, build, root)
        env = dict(os.environ)
        env.update(HOME=os.path.join(root, "home"), XDG_RUNTIME_DIR=os.path.join(root, "run"),
                   LODE_DDS_DOMAIN=str(domain), PATH=os.path.join(build, "apps") + ":" + env["PATH"],
                   LODE_DOC_SOURCE=source, LODE_DOC_BUILD=build)
        env.pop("LODE_DDS_PEERS", None)
        env.pop("LODE_DDS_INTERFACES", None)
        # Output to a file, not a pipe: a background job (`lode run ... &`) keeps a pipe open
        # after the blocks end, and waiting for its end-of-file would wait for the job.
        log_path = os.path.join(root, "output.log")
        with open(log_path, "w") as log:
            proc = subprocess.Popen(["bash", "-c", script_for(blocks)], cwd=work, env=env, stdout=log,
                                    stderr=subprocess.STDOUT, text=True, start_new_session=True)
            try:
                rc = proc.wait(timeout=FILE_TIMEOUT_S)
                timed_out = False
            except subprocess.TimeoutExpired:
                timed_out = True
                rc = 124
            finally:
                # Whatever the blocks started in the background ends here: asked to stop
                # (a lode run drives its outputs safe and exits), killed after 10 s.
                end_process_group(proc.pid, signal.SIGKILL if timed_out else signal.SIGTERM)
                proc.wait()
        output = open(log_path, encoding="utf-8", errors="replace").read()
        if timed_out:
            output += f"\ndoc-test: FAILED: {display} took longer than {FILE_TIMEOUT_S} s\n"
        return rc, output
    finally:
        shutil.rmtree(root, ignore_errors=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--source", required=True)
    ap.add_argument("--build", required=True)
    ap.add_argument("files", nargs="*")
    a = ap.parse_args()
    source, build = os.path.realpath(a.source), os.path.realpath(a.build)
    files = a.files or [os.path.join(source, "README.md")] + sorted(glob.glob(os.path.join(source, "docs", "*.md")))

    problems, plan = [], []
    for path in files:
        display = os.path.relpath(path, source)
        runnable, skipped = [], 0
        for block in fenced_blocks(path, display):
            kind = classify(block)
            if kind is None:
                continue
            if kind[0] == "error":
                problems.append(f"{block.where}: {kind[1]}")
            elif kind[0] == "skip":
                skipped += 1
            else:
                runnable.append((block, kind[1]))
        plan.append((display, runnable, skipped))
    if problems:
        print("\n".join(problems))
        print(f"doc-test: {len(problems)} shell blocks are neither runnable nor given a reason")
        return 1

    domain, _lock = take_private_domain()
    print(f"doc-test: private DDS domain {domain}")
    failed = 0
    for display, runnable, skipped in plan:
        if not runnable:
            print(f"ok: {display}: no runnable blocks ({skipped} shown only)")
            continue
        rc, output = run_file(display, runnable, source, build, domain)
        if rc == 0:
            print(f"ok: {display}: {len(runnable)} blocks run ({skipped} shown only)")
        else:
            failed += 1
            print(f"FAIL: {display} (exit {rc}); its output:")
            print(output.rstrip())
    total = sum(len(r) for _, r, _ in plan)
    print(f"doc-test: {total} blocks in {len(plan)} files, {failed} files failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
