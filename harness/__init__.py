"""What the tests and the benchmarks under ``tools/`` share, outside the package: the simulated
robot on a lockstep link with the project's configurations (:mod:`.support`), closed-loop plants
written independently of ``drive_bridge.sim`` (:mod:`.plants`), the fuzzed inputs of every reader
(:mod:`.fuzzing`) and the faults injected into a parameter write (:mod:`.write_faults`). Tests and
tools import it; it imports neither."""
