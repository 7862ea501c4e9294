"""No frame from the bus ends a simulated drive's service: RPDOs mapped onto every writable kind
of object and SDO requests, their bytes drawn by hypothesis, sent to the simulated drives in
lockstep; after each, every drive answers SDO and sends its heartbeat (a bad value is an EMCY)."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from harness.support import Bench, clean_config

pytestmark = pytest.mark.slow

#: what RPDO2..4 of every drive carry: mode, controlword, the targets of each mode, offsets, profile
MAPPED = {2: (0x6060, 0x6040, 0x607A), 3: (0x60FF, 0x6071, 0x60B2), 4: (0x6081, 0x60B1)}


@pytest.fixture(scope="module")
def bench():
    bench = Bench(clean_config())
    for node in bench.nodes.values():
        node.sdo[0x1017].raw = 20  # heartbeat producer, 20 ms
        node.rpdo.read()
        for number, objects in MAPPED.items():
            pdo = node.rpdo[number]
            pdo.clear()
            for index in objects:
                pdo.add_variable(index)
            pdo.cob_id = 0x100 * (number + 1) + node.id
            pdo.trans_type = 255
            pdo.enabled = True
        node.rpdo.save()
    bench.net.nmt.state = "OPERATIONAL"
    yield bench
    bench.close()


def _serving(bench) -> None:
    beats: set[int] = set()

    def heard(cob: int, data: bytearray, ts: float) -> None:
        beats.add(cob - 0x700)

    for node in bench.nodes.values():
        bench.net.subscribe(0x700 + node.id, heard)
    bench.link.clock.sleep(0.05)
    for node in bench.nodes.values():
        bench.net.unsubscribe(0x700 + node.id, heard)  # only ours: canopen's NMT listens there too
    assert beats == {node.id for node in bench.nodes.values()}, beats
    for node in bench.nodes.values():
        assert node.sdo[0x1000].raw is not None


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    frames=st.lists(
        st.tuples(
            st.sampled_from([0x301, 0x401, 0x501, 0x302, 0x402, 0x502, 0x201, 0x601, 0x602, 0x000, 0x080]),
            st.binary(min_size=0, max_size=8),
        ),
        min_size=1,
        max_size=6,
    )
)
def test_no_frame_from_the_bus_ends_a_drives_service(bench, frames):
    for cob_id, data in frames:
        if cob_id == 0x000 and data[:1] in (b"\x02", b"\x80", b"\x81", b"\x82"):
            continue  # NMT stop and resets are the master's to send; they end PDO service by design
        bench.net.send_message(cob_id, data)
    bench.link.clock.sleep(0.01)
    for node in bench.nodes.values():  # the drives' answers to the frames drawn: not ours to read
        node.sdo.responses.queue.clear()
    _serving(bench)
