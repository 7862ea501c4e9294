"""The cyclic engine's host on the wall clock: a process of its own, nothing else in it.

In the master's process the streaming loop shares one interpreter lock with canopen's receiving
thread, the trace writer, python-can's heartbeat thread, the progress bar and whatever the
collector or a log call does; on a loaded 2-core machine that held a SYNC up by 13-39 ms.  The
engine's process imports python-can, numpy and the engine only, opens a handle of its own on the
master's bus, asks for SCHED_FIFO and locks its memory (saying which it got), freezes and
disables the cycle collector, and then runs each job it is handed:

* the job (:class:`~.engine.Job`, plain data) over a Unix socket, with the descriptor of one
  shared mapping holding every array of the run (setpoint table, feedback, SYNC stamps, control
  slots) and the :class:`~.port.TraceRing` the master drains into the trace file;
* its :class:`~.engine.Outcome` back when the axes are held or stopped.

It stops the axes by itself on SIGINT, SIGTERM, SIGHUP and when the master's process ends
(PR_SET_PDEATHSIG); it exits when the master closes the socket.

Where the bus lives in the master's process only (python-can's virtual bus), or a second
handle on it cannot be opened, the same engine runs as a thread there (:class:`EngineThread`),
and the run says so.
"""

from __future__ import annotations

import ctypes
import gc
import logging
import mmap
import os
import pickle
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable
from typing import cast

import numpy as np

from ..cia.buses import BusSpec
from ..interrupts import HANDLED
from .engine import STOP_REQUEST, Arrays, Engine, Job, Outcome, stop_code
from .port import BusPort, TraceRing
from .timing import RT_PRIORITY, lock_memory, raise_priority

log = logging.getLogger(__name__)

START_TIMEOUT_S = 60.0  # the child imports python-can and numpy
RING_FRAMES = 1 << 18  # ~50 s of a 3-axis 500 Hz stream: the master may fall that far behind
ALIGN = 64
_HEADER = struct.Struct("<I")  # length of each pickled message on the socket
PR_SET_PDEATHSIG = 1


class EngineError(RuntimeError):
    """The engine's process could not be started or ended without an outcome."""


def _layout(job: Job, ring_frames: int) -> tuple[list[tuple[str, str, tuple[int, ...], type, int]], int]:
    """Where each array of a run lies in its shared mapping: (owner, name, shape, type, offset), size."""
    out, offset = [], 0
    for owner, layout in (("arrays", Arrays.layout(job)), ("ring", TraceRing.layout(ring_frames))):
        for name, shape, dtype in layout:
            out.append((owner, name, shape, dtype, offset))
            size = int(np.prod(shape)) * np.dtype(dtype).itemsize
            offset += -(-max(size, 1) // ALIGN) * ALIGN
    return out, offset


def _views(buffer: mmap.mmap, job: Job, ring_frames: int) -> tuple[Arrays, TraceRing]:
    """The arrays of a run over its shared mapping (the same in both processes)."""
    places, _ = _layout(job, ring_frames)
    where = {(owner, name): (shape, dtype, offset) for owner, name, shape, dtype, offset in places}

    def allocator(owner: str) -> Callable[[tuple[int, ...], type], np.ndarray]:
        names = iter([name for o, name, *_ in places if o == owner])

        def allocate(shape: tuple[int, ...], dtype: type) -> np.ndarray:
            shape_, dtype_, offset = where[(owner, next(names))]
            return np.ndarray(shape_, dtype_, buffer=buffer, offset=offset)

        return allocate

    return Arrays(job, allocator("arrays")), TraceRing(ring_frames, allocator("ring"))


def _shared(size: int) -> tuple[int, mmap.mmap]:
    """A descriptor and a mapping of ``size`` bytes of memory to share with the engine's process."""
    if hasattr(os, "memfd_create"):
        fd = os.memfd_create("drive-bridge-run", getattr(os, "MFD_CLOEXEC", 0))
    else:  # pragma: no cover - POSIX without memfd
        handle = tempfile.TemporaryFile()
        fd = os.dup(handle.fileno())
        handle.close()
    os.ftruncate(fd, size)
    return fd, mmap.mmap(fd, size)


def _send(sock: socket.socket, obj: object, fds: list[int] | None = None) -> None:
    data = pickle.dumps(obj)
    if fds:
        socket.send_fds(sock, [_HEADER.pack(len(data))], fds)
        sock.sendall(data)
    else:
        sock.sendall(_HEADER.pack(len(data)) + data)


def _receive(sock: socket.socket) -> tuple[object, list[int]]:
    header, fds, _, _ = socket.recv_fds(sock, _HEADER.size, 4)
    if len(header) < _HEADER.size:
        raise EOFError("the other end closed the socket")
    (length,) = _HEADER.unpack(header)
    data = bytearray()
    while len(data) < length:
        chunk = sock.recv(length - len(data))
        if not chunk:
            raise EOFError("the other end closed the socket")
        data += chunk
    return pickle.loads(data), fds


class EngineProcess:
    """The cyclic engine in a child process with its own handle on the bus of ``spec``.

    Parameters
    ----------
    spec : BusSpec
        The bus.
    """

    def __init__(self, spec: BusSpec):
        self.spec = spec
        parent, child = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
        self._sock = parent
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        self.process = subprocess.Popen(
            [sys.executable, "-m", __name__, str(child.fileno())],
            pass_fds=(child.fileno(),),
            env=env,
            stdin=subprocess.DEVNULL,
        )
        child.close()
        parent.settimeout(START_TIMEOUT_S)
        try:
            _send(parent, spec)
            reply, _ = _receive(parent)
        except (OSError, EOFError) as exc:
            self.close()
            raise EngineError(f"the cyclic engine's process did not start ({exc})") from exc
        parent.settimeout(None)
        if not isinstance(reply, dict) or "error" in reply:
            self.close()
            raise EngineError(str(reply.get("error") if isinstance(reply, dict) else reply))
        self.granted: str = reply["granted"]
        self.pid = self.process.pid
        self.description = f"a process of its own (pid {self.pid}): {self.granted}"
        self._result: Outcome | None = None
        self._mapping: mmap.mmap | None = None

    def start(self, job: Job, fill: Callable[[Arrays], None]) -> tuple[Arrays, TraceRing]:
        """Lay out the run in shared memory, let ``fill`` write the setpoint table, hand it over.

        Parameters
        ----------
        job : Job
            The job.
        fill : callable
            Writes the setpoint table into the arrays.

        Returns
        -------
        arrays : Arrays
            The run's arrays, in shared memory.
        ring : TraceRing
            The frames' ring, in shared memory.
        """
        places, size = _layout(job, RING_FRAMES)
        fd, mapping = _shared(size)
        try:
            arrays, ring = _views(mapping, job, RING_FRAMES)
            fill(arrays)
            self._result = None
            _send(self._sock, ("run", job, RING_FRAMES, size), [fd])
        finally:
            os.close(fd)
        self._mapping = mapping
        return arrays, ring

    def result(self, timeout: float) -> Outcome | None:
        """The outcome once the engine has ended the run (None: still running).

        Parameters
        ----------
        timeout : float
            How long to wait for it [s].

        Returns
        -------
        Outcome or None
            The outcome.

        Raises
        ------
        EngineError
            The engine's process is gone.
        """
        self._sock.settimeout(timeout)
        try:
            reply, _ = _receive(self._sock)
        except TimeoutError:
            return None
        except (OSError, EOFError) as exc:
            code = self.process.poll()
            raise EngineError(
                f"the cyclic engine's process ended without an outcome (exit code {code}: {exc})"
            ) from exc
        finally:
            self._sock.settimeout(None)
        if isinstance(reply, Outcome):
            return reply
        raise EngineError(f"the cyclic engine answered {reply!r}")

    def close(self) -> None:
        """End the engine's process."""
        try:
            self._sock.close()
        finally:
            if self.process.poll() is None:
                try:
                    self.process.wait(timeout=5)
                except subprocess.TimeoutExpired:
                    self.process.kill()
                    self.process.wait()


class EngineThread:
    """The same engine as a thread of the master's process (python-can's virtual bus lives there).

    Parameters
    ----------
    spec : BusSpec
        The bus.
    why : str
        Why a thread (for :attr:`description`).
    """

    def __init__(self, spec: BusSpec, why: str):
        self.spec = spec
        self.pid = os.getpid()
        self.description = f"a thread of the master's process ({why})"
        self._bus = spec.open()
        self._thread: threading.Thread | None = None
        self._outcome: Outcome | None = None
        self._error: BaseException | None = None

    def start(self, job: Job, fill: Callable[[Arrays], None]) -> tuple[Arrays, TraceRing]:
        """:meth:`EngineProcess.start`, in this process's memory.

        Parameters
        ----------
        job : Job
            The job.
        fill : callable
            Writes the setpoint table into the arrays.

        Returns
        -------
        arrays : Arrays
            The run's arrays.
        ring : TraceRing
            The frames' ring.
        """
        arrays = Arrays(job, np.zeros)
        ring = TraceRing(RING_FRAMES, np.zeros)
        fill(arrays)
        self._outcome = self._error = None

        def run() -> None:
            try:
                self._outcome = Engine(job, arrays, BusPort(self._bus, ring, job.sync_from)).run()
            except BaseException as exc:  # noqa: BLE001 - handed to the master's thread
                self._error = exc

        self._thread = threading.Thread(target=run, name="cyclic-engine", daemon=True)
        self._thread.start()
        return arrays, ring

    def result(self, timeout: float) -> Outcome | None:
        """:meth:`EngineProcess.result`.

        Parameters
        ----------
        timeout : float
            How long to wait for it [s].

        Returns
        -------
        Outcome or None
            The outcome (None: still running).
        """
        assert self._thread is not None
        self._thread.join(timeout)
        if self._thread.is_alive():
            return None
        if self._error is not None:
            raise EngineError(f"the cyclic engine failed: {self._error}") from self._error
        return self._outcome

    def close(self) -> None:
        """Close the engine's handle on the bus."""
        self._bus.shutdown()


def engine_for(spec: BusSpec) -> EngineProcess | EngineThread:
    """The engine's host for the bus of ``spec``: a process of its own where the bus can be opened
    a second time, else a thread (said in :attr:`description`).

    Parameters
    ----------
    spec : BusSpec
        The bus.

    Returns
    -------
    EngineProcess or EngineThread
        The host.
    """
    if spec.in_process:
        return EngineThread(spec, f"python-can's {spec.interface} bus lives in that process")
    try:
        return EngineProcess(spec)
    except EngineError as exc:
        log.warning("the cyclic engine runs as a thread of this process: %s", exc)
        return EngineThread(spec, f"no process of its own: {exc}")


# ---------------------------------------------------------------------------------------- the child
def _real_time() -> str:
    """SCHED_FIFO for the process and its memory locked, each where granted; what was granted."""
    return f"{raise_priority(RT_PRIORITY)[0]}, {lock_memory()}"


def _serve(sock: socket.socket) -> None:
    """The child: open the bus, report, then run jobs until the master closes the socket."""
    spec, _ = _receive(sock)
    assert isinstance(spec, BusSpec)
    try:
        bus = spec.open()
    except Exception as exc:  # noqa: BLE001 - python-can raises many kinds: said to the master
        _send(sock, {"error": f"cannot open {spec.interface}:{spec.channel} a second time ({exc})"})
        return
    try:
        libc = ctypes.CDLL(None)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM)  # the master gone: stop the axes, then leave
    except (AttributeError, OSError):
        pass
    control: list[np.ndarray] = []  # the running job's control slots (for the signal handler)

    def stop(signum: int, frame: object) -> None:
        if control:
            control[0][STOP_REQUEST] = stop_code(HANDLED.get(signum, "SIGTERM"))

    for signum in HANDLED:
        signal.signal(signum, stop)
    granted = _real_time()
    gc.collect()
    gc.freeze()
    gc.disable()
    _send(sock, {"granted": granted})
    while True:
        try:
            message, fds = _receive(sock)
        except (EOFError, OSError):
            break
        _, job, ring_frames, size = cast(tuple[str, Job, int, int], message)
        mapping = mmap.mmap(fds[0], size)
        os.close(fds[0])
        arrays, ring = _views(mapping, job, ring_frames)
        control.append(arrays.control)
        try:
            outcome = Engine(job, arrays, BusPort(bus, ring, job.sync_from)).run()
        finally:
            control.clear()
        del arrays, ring
        gc.collect()  # between runs, never on the cyclic path
        try:
            mapping.close()
        except BufferError:  # a view still held: the mapping goes with it
            pass
        _send(sock, outcome)
    bus.shutdown()


def main(fd: str) -> None:
    """The engine's process: serve runs over the socket the master handed down.

    Parameters
    ----------
    fd : str
        The socket's file descriptor.
    """
    with socket.socket(fileno=int(fd)) as sock:
        _serve(sock)


if __name__ == "__main__":
    main(sys.argv[1])
