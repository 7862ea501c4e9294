"""The protocol floor (drive_bridge.cia) stands on python-can, canopen (and Lely's linter) and the package's leaves
(errors, outputs: nothing above them), and the CiA 301/402 vocabulary is written once: the
master, the parameters and the simulated drives read theirs from it and not from each other."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import drive_bridge

PACKAGE = Path(drive_bridge.__file__).parent
#: python-can, canopen, and Lely's dcf-tools (``dcf``: the EDS check runs its linter where installed)
ALLOWED = {"can", "canopen", "dcf", "__future__"} | set(sys.stdlib_module_names)
LEAVES = {"..errors", "..outputs"}  # the package's modules the floor may stand on


def imports(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            module = node.module or ""
            found.add("." * node.level + module if node.level else module.split(".")[0])
    return found


def test_the_floor_imports_nothing_of_the_house_above_it():
    for path in sorted((PACKAGE / "cia").glob("*.py")):
        above = {
            name
            for name in imports(path)
            if name not in ALLOWED | LEAVES and not (name.startswith(".") and not name.startswith(".."))
        }
        assert not above, f"{path.name} imports {sorted(above)}"
    for leaf in LEAVES:
        below = {name for name in imports(PACKAGE / f"{leaf[2:]}.py") if name.startswith(".")}
        assert below <= {".errors"}, f"{leaf[2:]}.py, which the floor stands on, imports {sorted(below)}"


def test_the_cia_402_vocabulary_is_written_once():
    """No module but the floor assigns a controlword, a mode number or a power state of its own."""
    vocabulary = {
        "CW_SHUTDOWN",
        "CW_SWITCH_ON",
        "CW_ENABLE",
        "CW_QUICK_STOP",
        "CW_HALT",
        "CW_FAULT_RESET",
        "CW_ENABLE_IP",
        "SW_FAULT",
        "SW_FOLLOWING",
        "CSP",
        "IP",
        "PP",
        "PV",
        "HM",
        "MODE_NAMES",
        "STATE_BITS",
        "STATUSWORD",
        "CONTROLWORD",
        "SYNC_COB_ID",
        "NMT_OPERATIONAL",
        "ERR_FOLLOWING",
        "ERR_RPDO_TIMEOUT",
        "EMCY_TEXT",
    }
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.parent.name == "cia":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Assign):
                names = {
                    t.id
                    for target in node.targets
                    for t in (target.elts if isinstance(target, ast.Tuple) else [target])
                    if isinstance(t, ast.Name)
                }
                assert not names & vocabulary, (
                    f"{path.relative_to(PACKAGE)} defines {sorted(names & vocabulary)}"
                )


def test_no_cia_object_number_stands_outside_the_floor():
    """Every CiA 301/402 object (0x1000-0x1FFF, 0x6000-0x67FF) the package uses is named once in
    ``drive_bridge/cia`` (:mod:`drive_bridge.cia.objects`): read with Python's tokenizer, no other
    module writes one as a number (comments and docstrings may cite them)."""
    import io
    import tokenize

    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.parent.name == "cia":
            continue
        for token in tokenize.generate_tokens(io.StringIO(path.read_text()).readline):
            if token.type != tokenize.NUMBER or not token.string.lower().startswith("0x"):
                continue
            value = int(token.string, 16)
            if 0x1000 <= value <= 0x1FFF or 0x6000 <= value <= 0x67FF:
                found.append(f"{path.relative_to(PACKAGE)}:{token.start[0]} {token.string}")
    assert not found, "object numbers outside drive_bridge/cia: " + ", ".join(found)
