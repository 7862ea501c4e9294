"""The project's EDS and the vendor files against CiA 306, Lely's dcf-tools and canopen."""

from __future__ import annotations

import gc
import subprocess

import canopen
import pytest

from drive_bridge.cia.edscheck import check
from drive_bridge.cia.od import float_bits, float_from_bits, load_od
from drive_bridge.cli import main
from harness.paths import VENDOR_EDS
from harness.support import EDS, tool

pytestmark = pytest.mark.third_party

DCFCHK = tool("dcfchk")


def test_the_project_eds_is_cia_306_and_every_tool_reads_it(capsys):
    report = check(EDS)
    assert report.findings == [] and report.standard
    raw = canopen.import_od(str(EDS), 1)  # canopen as it is: the file loads
    assert raw[0x2000][1].default is None and raw[0x2000][1].default_raw == "0x43160000"
    od = load_od(EDS, 1)  # and drive-bridge reads the REAL32 bit patterns
    assert od[0x2000][1].default == 150.0 and od[0x2000][3].default == pytest.approx(0.12)
    assert main(["check-eds", str(EDS)]) == 0
    out = capsys.readouterr().out
    assert "CiA 306" in out and "cyclic synchronous position (8)" in out


def test_what_the_collector_frees_during_lelys_lint_is_none_of_its_findings(monkeypatch):
    """A file other code left open in a reference cycle, freed by the garbage collector while Lely
    lints: its ResourceWarning is not about the EDS (one made the project's EDS "not standard" in
    the suite beside two CPU-bound loops); Lely's own findings still are (the vendor files' test)."""
    lint = pytest.importorskip("dcf.lint")
    real = lint.lint

    def lint_while_the_collector_runs(cfg):
        left_open = [open(EDS, encoding="utf-8")]
        left_open.append(left_open)  # a cycle: only the collector frees the file
        del left_open
        gc.collect()
        return real(cfg)

    monkeypatch.setattr(lint, "lint", lint_while_the_collector_runs)
    report = check(EDS)
    assert report.lely == [] and report.standard


@pytest.mark.skipif(DCFCHK is None, reason="Lely's dcf-tools not installed (pip install dcf-tools)")
def test_lely_dcfchk_passes_the_project_eds():
    result = subprocess.run([DCFCHK, "-n", "1", str(EDS)], capture_output=True, text=True)
    assert result.returncode == 0 and "Warning" not in result.stderr, result.stderr


def test_float_bit_patterns_round_trip():
    for value in (0.0, 150.0, 0.12, -3.5e-5, 1e30):
        assert float_from_bits(float_bits(value, 0x0008), 0x0008) == pytest.approx(value, rel=1e-7)
        assert float_from_bits(float_bits(value, 0x0011), 0x0011) == value
    assert float_from_bits("1.5", 0x0008) is None


@pytest.mark.skipif(not VENDOR_EDS.is_dir(), reason="../shared/eds-vendor not present")
def test_vendor_files_are_read_as_they_are_and_what_is_not_standard_is_said(capsys):
    """The vendors' files load whatever Lely says of them; check-eds names what it finds (Lely's
    findings when installed, the project's own CiA 306 checks always) and exits 1."""
    pilz = VENDOR_EDS / "pilz_prbt_0_1.dcf"
    assert load_od(pilz, 3)[0x6502].default is not None
    code = main(["check-eds", str(pilz), str(VENDOR_EDS / "maxon_epos2_50-5.eds")])
    out = capsys.readouterr().out
    assert (
        "drive-bridge: modes (0x6502): profile position (1), velocity (2), interpolated position (7)" in out
    )
    assert "0x6502 has no DefaultValue here" in out  # EPOS2: read from the drive
    if DCFCHK:
        assert code == 1 and "NOT standard" in out and "lely: " in out
    for path in sorted(VENDOR_EDS.glob("*.[ed][dc][sf]")):
        load_od(path, 1)


def test_a_hand_written_file_with_the_usual_mistakes(tmp_path, capsys):
    path = tmp_path / "bad.eds"
    path.write_text(
        "[FileInfo]\nFileName=bad.eds\n[MandatoryObjects]\nSupportedObjects=2\n1=0x1000\n2=0x1018\n"
        "[1000]\nParameterName=Device type\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\n"
        "DefaultValue=0x00020192\nPDOMapping=0\nDescription=a key CiA 306 lacks\n"
        "[2000]\nParameterName=Gain\nObjectType=0x7\nDataType=0x0008\nAccessType=rw\n"
        "DefaultValue=0.5\nPDOMapping=0\n"
        "[1400sub1]\nParameterName=COB-ID\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\n"
        "DefaultValue=0x200+$NODEID\nPDOMapping=0\n"
    )
    found = "\n".join(check(path).findings)
    assert "[1000]: Description (no such key in CiA 306)" in found
    assert "[2000] DefaultValue=0.5: a decimal REAL" in found
    assert "$NODEID in another form" in found
    assert "mandatory object 0x1001 is not described" in found
    assert "object 0x1018 is listed but has no [1018] section" in found
    assert "[2000] is described but not listed" in found
    assert "canopen cannot import it" in found  # [1400sub1] without its [1400]
    assert main(["check-eds", str(path)]) == 1
    assert main(["check-eds", str(tmp_path / "missing.eds")]) == 2
    assert "no such EDS/DCF file" in capsys.readouterr().err


def test_each_load_is_its_own_object_dictionary_and_a_changed_file_is_read_again(tmp_path):
    """A file is parsed once per content and node id; every call still gets a dictionary of its own."""
    path = tmp_path / "drive.eds"
    path.write_bytes(EDS.read_bytes())
    a, b = load_od(path, 2), load_od(path, 2)
    assert a is not b and a[0x1017].default == b[0x1017].default
    a[0x1017].default = 4321  # one user's change stays its own
    assert b[0x1017].default != 4321 and load_od(path, 2)[0x1017].default != 4321
    assert load_od(path, 3)[0x1400][1].default == 0x200 + 3  # $NODEID resolved for the node asked for
    text = path.read_text()
    at = text.index("[1017]")
    path.write_text(text[:at] + text[at:].replace("DefaultValue=0", "DefaultValue=250", 1))
    assert load_od(path, 2)[0x1017].default == 250  # the file changed: read again
