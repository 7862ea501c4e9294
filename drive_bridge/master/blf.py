"""The raw trace's BLF file, written in batches.

:class:`BatchedBLFWriter` is python-can's ``BLFWriter`` whose classic CAN frames are packed a
container's worth at a time with numpy instead of three ``struct`` calls and four list appends
each: a campaign puts millions of frames on the bus, and the per-frame writer was a sixth of a
lockstep cycle.  The file is byte for byte the one ``BLFWriter`` writes for the same frames
(``tests/master/test_blf.py`` compares them); error and CAN FD frames still go through
``BLFWriter`` itself, after the frames before them.  With ``container_thread`` a full container is
compressed and written by a thread of its own, in order (zlib lets go of the GIL: on a second core
the frames go on being packed meanwhile) -- for one thread that does everything (a lockstep link),
not beside threads that keep time: an ordinary thread preempted while it holds the GIL would hold
them up.

Relies on these internals of python-can's ``BLFWriter`` (pinned by that test, bounded in
pyproject.toml): the uncompressed ``_buffer`` (a list of bytes) and ``_buffer_size``, ``_flush``
(which compresses the first ``max_container_size`` bytes into a container), ``object_count``,
``start_timestamp`` (the first frame's time truncated to ms) and ``stop_timestamp``.
"""

from __future__ import annotations

import os
import zlib
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import can
import numpy as np
from can.io.blf import (
    CAN_MESSAGE,
    CAN_MSG_EXT,
    DIR,
    LOG_CONTAINER,
    LOG_CONTAINER_STRUCT,
    NO_COMPRESSION,
    OBJ_HEADER_BASE_STRUCT,
    REMOTE_FLAG,
    TIME_ONE_NANS,
    ZLIB_DEFLATE,
)
from can.util import channel2int

#: one CAN_MESSAGE object: base header, header v1 (flags, client, version, time [ns]), the frame
_OBJECT = np.dtype(
    [
        ("signature", "S4"),
        ("header_size", "<u2"),
        ("header_version", "<u2"),
        ("object_size", "<u4"),
        ("object_type", "<u4"),
        ("time_flags", "<u4"),
        ("client", "<u2"),
        ("version", "<u2"),
        ("time_ns", "<u8"),
        ("channel", "<u2"),
        ("flags", "u1"),
        ("dlc", "u1"),
        ("can_id", "<u4"),
        ("data", "S8"),
    ]
)
_HEADER_SIZE = 32


class BatchedBLFWriter(can.BLFWriter):
    """``BLFWriter`` that packs classic frames in batches; ``epoch`` [s] is added to every time stamp
    it is given (a lockstep link's clock starts at 0); ``container_thread``: containers compressed
    and written by a thread of their own.

    Parameters
    ----------
    file : str or os.PathLike
        The BLF file.
    epoch : float
        Added to every time stamp [s].
    container_thread : bool
        Containers compressed and written by a thread of their own.
    **kwargs : object
        python-can's ``BLFWriter`` arguments.
    """

    def __init__(
        self,
        file: str | os.PathLike[str],
        *,
        epoch: float = 0.0,
        container_thread: bool = False,
        **kwargs: Any,
    ):
        super().__init__(file, **kwargs)
        self.epoch = epoch
        self._rows: list[tuple[float, int, int, int, int, bytes]] = []
        self._batch = self.max_container_size // _OBJECT.itemsize + 1
        self._channels: dict[Any, int] = {}
        self._containers = (
            ThreadPoolExecutor(1, thread_name_prefix="blf-container") if container_thread else None
        )
        self._written: list[Future] = []

    def on_message_received(self, msg: can.Message) -> None:
        if msg.is_error_frame or msg.is_fd:
            super().on_message_received(msg)
            return
        channel = self._channels.get(msg.channel)
        if channel is None:
            number = channel2int(msg.channel)
            channel = self._channels[msg.channel] = self.channel if number is None else number + 1
        flags = REMOTE_FLAG if msg.is_remote_frame else 0
        if not msg.is_rx:
            flags |= DIR
        self._rows.append(
            (
                msg.timestamp,
                channel,
                flags,
                msg.dlc,
                msg.arbitration_id | CAN_MSG_EXT if msg.is_extended_id else msg.arbitration_id,
                bytes(msg.data),
            )
        )
        if len(self._rows) >= self._batch:
            self._pack()

    def _pack(self) -> None:
        """Append the frames held so far to the uncompressed buffer, as BLFWriter's _add_object would
        one by one, and compress every full container."""
        rows, self._rows = self._rows, []
        if not rows:
            return
        stamps, channels, flags, dlcs, ids, data = zip(*rows)
        t = np.array(stamps, dtype=np.float64) + self.epoch
        if self.start_timestamp is None:
            self.start_timestamp = int(t[0] * 1000) / 1000
        self.stop_timestamp = float(t[-1])
        obj = np.zeros(len(rows), _OBJECT)
        obj["signature"] = b"LOBJ"
        obj["header_size"] = _HEADER_SIZE
        obj["header_version"] = 1
        obj["object_size"] = _OBJECT.itemsize
        obj["object_type"] = CAN_MESSAGE
        obj["time_flags"] = TIME_ONE_NANS
        obj["time_ns"] = np.maximum(((t - self.start_timestamp) * 1e9).astype(np.int64), 0)
        obj["channel"], obj["flags"], obj["dlc"], obj["can_id"] = channels, flags, dlcs, ids
        obj["data"] = data
        self._buffer.append(obj.tobytes())
        self._buffer_size += obj.nbytes
        self.object_count += len(rows)
        while self._buffer_size >= self.max_container_size:
            self._flush()

    def _flush(self) -> None:
        """As BLFWriter's: the first ``max_container_size`` bytes held make a container, the rest
        waits for the next; compressed and written by the container thread, in order."""
        if self._containers is None or self.file.closed:
            super()._flush()
            return
        buffer = b"".join(self._buffer)
        if not buffer:
            return
        self._buffer = [buffer[self.max_container_size :]]
        self._buffer_size = len(self._buffer[0])
        chunk = buffer[: self.max_container_size]
        self.uncompressed_size += OBJ_HEADER_BASE_STRUCT.size + LOG_CONTAINER_STRUCT.size + len(chunk)
        for done in [f for f in self._written if f.done()]:
            done.result()  # a container that could not be written stops the trace here
            self._written.remove(done)
        self._written.append(self._containers.submit(self._write_container, chunk))

    def _write_container(self, chunk: bytes) -> None:
        if self.compression_level:
            data, method = zlib.compress(chunk, self.compression_level), ZLIB_DEFLATE
        else:
            data, method = chunk, NO_COMPRESSION
        size = OBJ_HEADER_BASE_STRUCT.size + LOG_CONTAINER_STRUCT.size + len(data)
        self.file.write(
            OBJ_HEADER_BASE_STRUCT.pack(b"LOBJ", OBJ_HEADER_BASE_STRUCT.size, 1, size, LOG_CONTAINER)
            + LOG_CONTAINER_STRUCT.pack(method, len(chunk))
            + data
            + b"\x00" * (size % 4)
        )

    def _add_object(self, obj_type: int, data: bytes, timestamp: float | None = None) -> None:
        self._pack()  # error and FD frames, markers: after the frames before them
        super()._add_object(obj_type, data, None if timestamp is None else timestamp + self.epoch)

    def file_size(self) -> int:
        return super().file_size() + len(self._rows) * _OBJECT.itemsize

    def stop(self) -> None:
        self._pack()
        if self._containers is not None:
            self._containers.shutdown(wait=True)
            self._containers = None
            for written in self._written:
                written.result()
        super().stop()
