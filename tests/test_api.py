"""The package's face: the public API a pipeline imports from ``drive_bridge`` itself, each name
imported on first use, and one version."""

from __future__ import annotations

import pkgutil
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

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


#: every module of the package (not ``python -m drive_bridge``, which runs the command line, nor the
#: history database's migrations, Alembic's scripts)
MODULES = sorted(
    m.name
    for m in pkgutil.walk_packages(drive_bridge.__path__, "drive_bridge.")
    if not m.name.endswith("__main__") and ".migrations" not in m.name
)
#: numpydoc's checks of the sections: every parameter documented and none unknown, a Returns
#: section where something is returned, a docstring at all
SECTIONS = ("PR01", "PR02", "RT01", "GL08")


def _public_objects() -> Iterator[tuple[str, object]]:
    """(dotted name, object) of every public function and class each module defines (not those it
    imports; numba's compiled functions among them), and of the public methods and properties each
    class defines itself (an override of a base class's is documented there, as Sphinx's autodoc
    inherits it)."""
    import importlib
    import inspect

    for module in MODULES:
        for name, value in vars(importlib.import_module(module)).items():
            defined = getattr(value, "py_func", value)  # a numba dispatcher: its Python function
            if name.startswith("_") or not (
                (inspect.isfunction(defined) or inspect.isclass(defined)) and defined.__module__ == module
            ):
                continue
            yield f"{module}.{name}", value
            if inspect.isclass(value):
                for member, attribute in vars(value).items():
                    if (
                        not member.startswith("_")
                        and (
                            inspect.isfunction(attribute)
                            or isinstance(attribute, (property, classmethod, staticmethod))
                        )
                        and not any(member in vars(base) for base in value.__mro__[1:])
                    ):
                        yield f"{module}.{name}.{member}", attribute


def _constructor_elsewhere(obj: object) -> bool:
    """Whether ``obj`` is a class whose constructor is documented elsewhere: a typing.Protocol (an
    interface, none to document) or a class that inherits its base's."""
    import inspect

    return inspect.isclass(obj) and (getattr(obj, "_is_protocol", False) or "__init__" not in vars(obj))


@pytest.mark.slow  # it imports every module of the package: CI's, not the quick run's
def test_every_public_function_has_numpydocs_sections():
    """As python-control writes them (numpydoc's own validator): Parameters, with units in
    brackets, and Returns on every public function, method and class of every module (the package's
    names, what they return and take, what the Python tutorial imports among them)."""
    from numpydoc.validate import validate

    missing = [
        f"{name}: {code} {message}"
        for name, obj in _public_objects()
        for code, message in validate(name)["errors"]
        if code in SECTIONS and not (code in ("PR01", "PR02") and _constructor_elsewhere(obj))
    ]
    assert not missing, "\n".join(missing)
