"""Stalls of the master as a test input: every process of a running master -- its main process and
its cyclic engine's, never the simulated drives' -- stopped together (SIGSTOP) and let go again
(SIGCONT), for chosen lengths at random moments, as a host that is not real-time stalls it (a
laptop, an industrial PC without PREEMPT_RT, a VM: 10-100 ms and more).

The injector is a process of its own (a thread of the master would be stopped with it):

    python -m harness.stalls --master PID [--length 0.2] [--every 2.0] [--seed 0] [--log stalls.jsonl]

Each stall is a line of ``--log`` (JSON: when it began on the wall clock, how long it lasted, the
processes stopped), written once the processes run again.  The waits between stalls are drawn
from an exponential distribution of mean ``--every`` (a Poisson process: no rhythm a master could
lock onto), seeded.  It ends with the master's main process.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

ENGINE = "drive_bridge.master.coprocess"  # the cyclic engine's process, as its command line names it
SIMULATOR = "drive_bridge.sim.process"  # the wall-clock simulated drives' process
DRIVES = "drive_bridge.sim.process"  # the simulated drives' (never stopped)


def children(pid: int) -> list[int]:
    """Every descendant of process ``pid``, from /proc.

    Parameters
    ----------
    pid : int
        The process.

    Returns
    -------
    list of int
        Its children, theirs, and so on.
    """
    parents: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        parents.setdefault(int(fields[1]), []).append(int(entry.name))
    out, todo = [], [pid]
    while todo:
        for child in parents.get(todo.pop(), []):
            out.append(child)
            todo.append(child)
    return out


def command_line(pid: int) -> str:
    """Process ``pid``'s command line, its arguments joined by spaces ("" where it is gone)."""
    try:
        return (Path("/proc") / str(pid) / "cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


def master_processes(master: int) -> list[int]:
    """The master's main process and its cyclic engine's (a child that runs :data:`ENGINE`); the
    simulated drives' process and anything else it started are left running."""
    return [master] + [pid for pid in children(master) if ENGINE in command_line(pid)]


def simulator_process(master: int) -> int:
    """The wall-clock simulated drives' process the master ``master`` started (held up as a host
    holds a process up: what a real drive never is, and what its catching up must survive)."""
    return next(pid for pid in children(master) if SIMULATOR in command_line(pid))


def stall(pids: list[int], length_s: float) -> float:
    """Stop ``pids`` together for ``length_s`` [s] and let them go again; how long they were stopped.

    Parameters
    ----------
    pids : list of int
        The processes.
    length_s : float
        [s].

    Returns
    -------
    float
        [s], as measured.
    """
    stopped = []
    t0 = time.monotonic()
    try:
        for pid in pids:
            try:
                os.kill(pid, signal.SIGSTOP)
                stopped.append(pid)
            except ProcessLookupError:
                pass
        time.sleep(max(0.0, length_s - (time.monotonic() - t0)))
    finally:
        for pid in stopped:
            try:
                os.kill(pid, signal.SIGCONT)
            except ProcessLookupError:
                pass
    return time.monotonic() - t0


def inject(master: int, length_s: float, every_s: float, seed: int, log: Path | None) -> int:
    """Stall the master's processes (:func:`master_processes`) for ``length_s`` at random moments,
    ``every_s`` apart on average, until its main process ends; the stalls made.

    Parameters
    ----------
    master : int
        The master's main process.
    length_s : float
        Each stall [s].
    every_s : float
        The mean wait between stalls [s].
    seed : int
        The waits' seed.
    log : Path, optional
        Where each stall is written, a JSON line.

    Returns
    -------
    int
        The stalls made.
    """
    draws = random.Random(seed)
    made = 0
    out = log.open("a", buffering=1) if log is not None else None
    try:
        while True:
            time.sleep(draws.expovariate(1.0 / every_s))
            if not os.path.exists(f"/proc/{master}"):
                return made
            pids = master_processes(master)
            began = time.time()
            lasted = stall(pids, length_s)
            made += 1
            if out is not None:
                out.write(json.dumps({"began": began, "lasted_s": round(lasted, 4), "pids": pids}) + "\n")
    finally:
        if out is not None:
            out.close()


def injector(master: int, length_s: float, every_s: float, seed: int, log: Path) -> subprocess.Popen:
    """:func:`inject` started in a process of its own (end it with ``terminate()``).

    Parameters
    ----------
    master : int
        The master's main process.
    length_s, every_s : float
        Each stall, and the mean wait between them [s].
    seed : int
        The waits' seed.
    log : Path
        Where the stalls are written.

    Returns
    -------
    subprocess.Popen
        The injector.
    """
    root = Path(__file__).resolve().parents[1]
    command = [sys.executable, "-m", "harness.stalls", "--master", str(master), "--length", str(length_s)]
    command += ["--every", str(every_s), "--seed", str(seed), "--log", str(log)]
    return subprocess.Popen(command, cwd=root)


def stalling_at(pid_of, stalls, seconds):
    """An ``on_plan`` hook (:func:`drive_bridge.recorder.record`) whose progress stops the process
    ``pid_of()`` names (or the processes, a list) together for ``seconds`` at each fraction of the
    plan in ``stalls``, once each: (the hook, the plan rows it stopped at so far)."""
    done = []

    def on_plan(plan):
        rows = [round(f * len(plan.demand)) for f in stalls]

        def progress(k):
            if len(done) < len(rows) and k >= rows[len(done)]:
                pids = pid_of()
                stall(pids if isinstance(pids, list) else [pids], seconds)
                done.append(k)

        return progress

    return on_plan, done


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--master", type=int, required=True, help="the master's main process")
    parser.add_argument("--length", type=float, default=0.2, help="each stall [s]")
    parser.add_argument("--every", type=float, default=2.0, help="the mean wait between stalls [s]")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--log", type=Path, default=None, help="each stall as a JSON line")
    args = parser.parse_args()
    inject(args.master, args.length, args.every, args.seed, args.log)


if __name__ == "__main__":
    main()
