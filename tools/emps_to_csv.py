"""Convert the EMPS benchmark (a real ball-screw axis) to a drive-bridge log CSV.

    python tools/emps_to_csv.py ../shared/data/emps/DATA_EMPS.mat out/emps.csv

Columns: ``time_s``, ``emps_position_m`` (qm, load side) and ``emps_force_N``
(gtau · vir, the EMPS reference's force); the data is read in place from the
.mat file (see ``../shared/data/emps/SOURCE.md``), never copied.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy import io

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from drive_bridge.outputs import write_table  # noqa: E402

AXIS = "emps"


def emps_columns(mat_path: str | Path) -> dict[str, np.ndarray]:
    d = io.loadmat(str(mat_path))
    gtau = float(np.squeeze(d["gtau"]))
    return {
        "time_s": np.ravel(d["t"]),
        f"{AXIS}_position_m": np.ravel(d["qm"]),
        f"{AXIS}_force_N": gtau * np.ravel(d["vir"]),
    }


def write_csv(mat_path: str | Path, csv_path: str | Path) -> Path:
    cols = emps_columns(mat_path)
    csv_path = Path(csv_path)
    csv_path.parent.mkdir(parents=True, exist_ok=True)
    return write_table(csv_path, list(cols), np.column_stack(list(cols.values())), ["%.6f", "%.10g", "%.10g"])


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mat", help="DATA_EMPS.mat or DATA_EMPS_PULSES.mat")
    parser.add_argument("csv", help="CSV to write")
    args = parser.parse_args()
    print(f"wrote {write_csv(args.mat, args.csv)}")
