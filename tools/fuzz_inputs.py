"""Seeded fuzz run over every reader of drive-bridge: counts inputs per kind, clean refusals,
tracebacks (any exception that is not a DriveBridgeError) and hangs (an input over 20 s).

    python tools/fuzz_inputs.py [--per-kind 300] [--seed 1]

The inputs come from harness/fuzzing.py (hypothesis strategies); the test suite runs the same
readers with a few dozen inputs each (tests/test_fuzz.py).  Exit 1 when any traceback or hang.
"""

from __future__ import annotations

import argparse
import collections
import signal
import sys
import tempfile
import time
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from hypothesis import HealthCheck, given, seed, settings  # noqa: E402

from drive_bridge.errors import DriveBridgeError  # noqa: E402
from harness.fuzzing import kinds, record_trace  # noqa: E402

HANG_S = 20


class Hang(Exception):
    pass


def _alarm(signum, frame):
    raise Hang()


def fuzz(name, kind, args, counts, first) -> None:
    """Run ``args.per_kind`` inputs of ``kind`` through its reader, counting what happens."""

    @seed(args.seed)
    @settings(
        max_examples=args.per_kind, deadline=None, database=None, suppress_health_check=list(HealthCheck)
    )
    @given(kind.strategy)
    def run(value):
        counts[name]["inputs"] += 1
        with tempfile.TemporaryDirectory() as work:
            inputs = Path(work) / "in"  # the readers may put files beside it (an EDS)
            inputs.mkdir()
            signal.alarm(HANG_S)
            try:
                kind.read(value, inputs)
                counts[name]["accepted"] += 1
            except DriveBridgeError:
                counts[name]["refused"] += 1
            except Hang:
                counts[name]["hangs"] += 1
            except BaseException as exc:  # noqa: BLE001 -- a traceback is what we count
                counts[name]["tracebacks"] += 1
                first.setdefault((name, type(exc).__name__), (repr(value)[:300], traceback.format_exc()))
            finally:
                signal.alarm(0)

    run()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per-kind", type=int, default=300)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    signal.signal(signal.SIGALRM, _alarm)
    with tempfile.TemporaryDirectory() as tmp:
        all_kinds = kinds(*record_trace(Path(tmp)))
    counts = collections.defaultdict(collections.Counter)
    first = {}
    t0 = time.perf_counter()
    for name, kind in all_kinds.items():
        fuzz(name, kind, args, counts, first)
    total = collections.Counter()

    print(f"{'kind':<16} {'inputs':>7} {'accepted':>9} {'refused':>8} {'tracebacks':>11} {'hangs':>6}")
    for name, c in counts.items():
        total.update(c)
        print(
            f"{name:<16} {c['inputs']:>7} {c['accepted']:>9} {c['refused']:>8} {c['tracebacks']:>11} {c['hangs']:>6}"
        )
    print(
        f"{'all':<16} {total['inputs']:>7} {total['accepted']:>9} {total['refused']:>8} "
        f"{total['tracebacks']:>11} {total['hangs']:>6}   ({time.perf_counter() - t0:.0f} s, seed {args.seed})"
    )
    for (name, exc), (value, tb) in first.items():
        print(f"\n--- {name}: {exc} on {value}\n{tb}")
    return 1 if total["tracebacks"] or total["hangs"] else 0


if __name__ == "__main__":
    sys.exit(main())
