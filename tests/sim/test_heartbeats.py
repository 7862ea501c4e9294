"""A simulated drive's heartbeat consumer (0x1016) as CiA 301 has it: a node is watched from its
first heartbeat, found silent once after its consumer time, and watched again from its next."""

from __future__ import annotations

import math

from drive_bridge.sim.heartbeats import HeartbeatConsumer


def objects(entries: dict[int, int]):
    return lambda index, sub: entries.get(sub) if index == 0x1016 else None


def test_a_node_is_watched_from_its_first_heartbeat_and_found_silent_once():
    entries = {1: (0x7F << 16) | 100, 2: 0}  # the master (node 127), 100 ms; sub 2 unused
    consumer = HeartbeatConsumer(objects(entries))
    assert consumer.watched == {0x7F: 0.1}
    assert list(consumer.fallen_silent(10.0)) == [] and consumer.next_due() == math.inf  # never heard yet
    consumer.heard(0x7F, 1.0)
    consumer.heard(5, 1.0)  # not watched: nothing
    assert consumer.next_due() == 1.1
    assert list(consumer.fallen_silent(1.1)) == []  # exactly its consumer time: not yet
    assert list(consumer.fallen_silent(1.2)) == [0x7F]
    assert list(consumer.fallen_silent(1.3)) == []  # once
    consumer.heard(0x7F, 2.0)
    assert list(consumer.fallen_silent(2.2)) == [0x7F]


def test_rewriting_0x1016_forgets_a_node_no_longer_watched():
    entries = {1: (0x7F << 16) | 100}
    consumer = HeartbeatConsumer(objects(entries))
    consumer.heard(0x7F, 1.0)
    entries[1] = 0  # the consumer switched off
    consumer.configure()
    assert consumer.watched == {} and list(consumer.fallen_silent(5.0)) == []
