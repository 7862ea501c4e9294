"""The package's face: the public API a pipeline imports from ``drive_bridge`` itself, each name
imported on first use, and one version."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import drive_bridge

ROOT = Path(__file__).resolve().parents[1]


def test_every_public_name_is_the_function_or_class_of_its_module():
    from drive_bridge.commissioning.run import commission
    from drive_bridge.config import load_bus_config
    from drive_bridge.connect import open_link
    from drive_bridge.ident.identify import identify
    from drive_bridge.params.write import write_drives
    from drive_bridge.session import Options, Session
    from drive_bridge.tuning.tune import tune

    expected = {
        "Session": Session,
        "Options": Options,
        "open_link": open_link,
        "load_bus_config": load_bus_config,
        "identify": identify,
        "tune": tune,
        "write_drives": write_drives,
        "commission": commission,
    }
    assert set(expected) <= set(drive_bridge.__all__) <= set(expected) | {"__version__"}
    for name, value in expected.items():
        assert getattr(drive_bridge, name) is value, name
    assert set(expected) <= set(dir(drive_bridge))


def test_importing_the_package_imports_none_of_the_layers_above():
    code = "import sys, drive_bridge; print(sorted(m for m in sys.modules if m.startswith('drive_bridge.')))"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert eval(loaded) == ["drive_bridge.version"]
    try:
        drive_bridge.no_such_name  # noqa: B018
    except AttributeError as exc:
        assert "no_such_name" in str(exc)
    else:
        raise AssertionError("an unknown name must raise AttributeError")


def test_the_version_is_the_one_pyproject_declares():
    declared = re.search(r'^version = "([^"]+)"', (ROOT / "pyproject.toml").read_text(), re.M)
    assert declared is not None and drive_bridge.__version__ == declared.group(1)


def test_the_command_line_starts_without_the_libraries_its_commands_load_when_they_run():
    """``drive-bridge --help`` and every command's start: python-control, matplotlib and scipy's
    signal processing (over a second to import here) are loaded by the commands that compute with
    them, not by the parser."""
    code = "import sys, drive_bridge.cli; print(sorted(m.split('.')[0] for m in sys.modules))"
    loaded = set(
        eval(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout)
    )
    assert not loaded & {"control", "matplotlib"}, loaded & {"control", "matplotlib"}
    code = "import sys, drive_bridge.cli; print('scipy.signal' in sys.modules)"
    assert (
        subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, check=True
        ).stdout.strip()
        == "False"
    )


def test_a_packages_names_are_its_functions_whatever_was_imported_before():
    """``from drive_bridge.ident import identify`` is the function even where the module of the same
    name was imported first (as the report's modules do), and the commissioning package's names,
    imported on first use, are run's."""
    code = (
        "import drive_bridge.ident.identify, drive_bridge.ident.presentation, drive_bridge.commissioning.run\n"
        "from drive_bridge.ident import identify, AxisResult\n"
        "from drive_bridge.commissioning import STEPS, commission, CommissionResult, Options\n"
        "from drive_bridge.commissioning import run\n"
        "import sys\n"
        "assert callable(identify) and identify is sys.modules['drive_bridge.ident.identify'].identify\n"
        "assert commission is run.commission and STEPS == run.STEPS and CommissionResult is run.CommissionResult\n"
        "import drive_bridge.session\n"
        "assert Options is drive_bridge.session.Options\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
