"""Configuration of the simulated robot: plant per axis, hidden effects, seed.

The effects listed here act on the simulated plant only; nothing on the bus
reveals them.  They exist to test identification on data with an effect that
nobody declared.  All values SI, motor side (rad, rad/s, Nm).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..yamlconf import Section, load_yaml

DEFAULT_CONFIG = Path(__file__).with_name("robot.yaml")
#: simulated robots shipped with the package, by the name ``--sim-config`` takes instead of a path
SHIPPED = {
    "robot": DEFAULT_CONFIG,
    "compliant": Path(__file__).with_name("robot_compliant.yaml"),
    "wearing": Path(__file__).with_name("robot_wearing.yaml"),
}

#: the range of each effect value the plant can run with (low, high)
RANGES = {
    "torque_Nm": (-100.0, 100.0),
    "amplitude_Nm": (-100.0, 100.0),
    "period_rad": (1e-3, 1e6),
    "phase_rad": (-100.0, 100.0),
    "velocity_rad_s": (1e-6, 1e6),
    "dc0_Nm": (-100.0, 100.0),
    "dc1_Nm_s_rad": (-100.0, 100.0),
    "coefficient_Nm_per_rad": (-100.0, 100.0),
    "fraction": (-10.0, 10.0),
    "time_constant_s": (1e-3, 1e9),
    "load_share": (1e-3, 0.999),
    "stiffness_Nm_rad": (1e-3, 1e9),
    "damping_Nm_s_rad": (0.0, 1e6),
    "c0_fraction_per_rad": (0.0, 1.0),
    "c1_fraction_per_rad": (0.0, 1.0),
}
#: an effect's keys that may be left out, and their value then (wear: one of the two frictions alone)
OPTIONAL = {"c0_fraction_per_rad": 0.0, "c1_fraction_per_rad": 0.0}
#: effect name -> {yaml key: kernel parameter name}
EFFECTS = {
    "load": {"torque_Nm": "LOAD"},
    "position_periodic": {"amplitude_Nm": "PER_AMP", "period_rad": "PER_PERIOD", "phase_rad": "PER_PHASE"},
    "stribeck": {"amplitude_Nm": "STR_AMP", "velocity_rad_s": "STR_VEL"},
    "direction_asymmetry": {"dc0_Nm": "ASYM_DC0", "dc1_Nm_s_rad": "ASYM_DC1"},
    "cross_axis": {"source": "CPL_SRC", "coefficient_Nm_per_rad": "CPL_COEF"},
    "drift": {"fraction": "DRIFT_FRAC", "time_constant_s": "DRIFT_TAU"},
    # wear: Coulomb and viscous friction rising with the motor's travel (a fraction of c0, c1 per rad)
    "wear": {"c0_fraction_per_rad": "WEAR_C0", "c1_fraction_per_rad": "WEAR_C1"},
    # a compliant transmission: that share of J behind a spring-damper (a two-mass mode)
    "compliance": {"load_share": "TM_SHARE", "stiffness_Nm_rad": "TM_K", "damping_Nm_s_rad": "TM_D"},
}


@dataclass
class Motor:
    """Motor and power stage.

    Parameters
    ----------
    R : float
        Winding resistance [Ω].
    L : float
        Winding inductance [H].
    kt : float
        Torque constant [Nm/A].
    vbus : float
        DC link voltage [V].
    rated_torque_Nm : float
        Rated torque [Nm] (0x6076).
    """

    R: float = 0.8
    L: float = 0.002
    kt: float = 0.2
    vbus: float = 60.0
    rated_torque_Nm: float = 1.27


@dataclass
class SimAxis:
    """One simulated axis: its plant, motor and drive, SI, motor side.

    Parameters
    ----------
    name : str
        The axis.
    node_id : int
        Its drive's node id.
    serial : int
        Its drive's serial number (0x1018:4).
    J : float
        Inertia [kg·m²].
    c0 : float
        Coulomb friction [Nm].
    c1 : float
        Viscous friction [Nm·s/rad].
    cp : float
        A torque proportional to position [Nm/rad] (the paper's cp).
    D : float
        A constant torque [Nm] (the paper's D).
    torque_noise_Nm : float
        The std of the noise on the measured torque [Nm].
    motor : Motor
        Motor and power stage.
    effects : dict
        The hidden effects, by name: {kernel parameter: value} (a coupling's source as an axis
        name).
    brake : bool
        A holding brake that holds the axis whenever the power stage is off.
    end_stops_rad : (float, float), optional
        Mechanical end stops [rad].
    initial_position_rad : float
        Where the axis stands at power-on [rad].
    saved_limits : SavedLimits, optional
        What the machine's integrator saved in the drive (None: the drive's factory values).
    """

    name: str
    node_id: int
    serial: int
    J: float
    c0: float
    c1: float
    cp: float = 0.0
    D: float = 0.0
    torque_noise_Nm: float = 0.0
    motor: Motor = field(default_factory=Motor)
    effects: dict = field(default_factory=dict)
    brake: bool = True
    end_stops_rad: tuple[float, float] | None = None
    initial_position_rad: float = 0.0
    saved_limits: SavedLimits | None = None


@dataclass(frozen=True)
class SavedLimits:
    """The limits a machine's drive holds from its commissioning (``saved_limits`` in the YAML).

    Parameters
    ----------
    stroke_rad : (float, float)
        The software position limits 0x607D [rad].
    max_velocity_rad_s : float
        The max profile velocity 0x607F [rad/s].
    acceleration_rad_s2 : float
        The profile acceleration and deceleration 0x6083 / 0x6084 [rad/s²].
    """

    stroke_rad: tuple[float, float]
    max_velocity_rad_s: float
    acceleration_rad_s2: float


@dataclass
class SimConfig:
    """The simulated robot (:func:`load_sim_config`).

    Parameters
    ----------
    axes : dict of str to SimAxis
        Per axis: its plant (J, c0, c1, the effects it hides, its noise), motor, brake, end stops
        and what its drive saved.
    seed : int
        Seed of the plant's noise (the same seed, the same log).
    path : Path, optional
        The YAML file it was read from.
    """

    axes: dict[str, SimAxis]
    seed: int = 0
    path: Path | None = None


def _span(sec: Section, key: str, required: bool = False) -> tuple[float, float] | None:
    """``key``: [low, high] in rad, low < high (None where it is not given and not ``required``)."""
    span = sec.get(key, list, ... if required else None)
    if span is None:
        return None
    if (
        len(span) != 2
        or not all(isinstance(v, (int, float)) and abs(v) < 1e6 for v in span)
        or span[0] >= span[1]
    ):
        raise sec.error(key, f"must be [low, high] in rad with low < high, got {span!r}")
    return float(span[0]), float(span[1])


def _saved_limits(sec: Section) -> SavedLimits | None:
    saved = sec.section("saved_limits", required=False)
    if not saved.keys():
        return None
    stroke = _span(saved, "stroke_rad", required=True)
    assert stroke is not None  # (required)
    out = SavedLimits(
        stroke,
        saved.get("max_velocity_rad_s", float, low=1e-6, high=1e5),
        saved.get("acceleration_rad_s2", float, low=1e-6, high=1e7),
    )
    saved.done()
    return out


def load_sim_config(path: str | Path = DEFAULT_CONFIG) -> SimConfig:
    """Read and check a simulator YAML file.

    Parameters
    ----------
    path : str or Path
        The file (see ``robot.yaml`` for the format), or a shipped robot by its name in
        :data:`SHIPPED`; default the shipped robot.

    Returns
    -------
    SimConfig
        The simulated robot.

    Raises
    ------
    ConfigError
        A key that does not hold, named with the file.
    """
    path = SHIPPED.get(str(path), Path(path))
    top = Section(path, "", load_yaml(path))
    seed = top.get("seed", int, 0, low=0, high=2**32 - 1)
    axes_sec = top.section("axes")
    axes: dict[str, SimAxis] = {}
    for name in axes_sec.keys():
        sec = axes_sec.section(name)
        plant = sec.section("plant")
        motor_sec = sec.section("motor", required=False)
        motor = Motor(
            **{
                k: motor_sec.get(k, float, getattr(Motor, k), low=1e-9, high=1e4)
                for k in ("R", "L", "kt", "vbus", "rated_torque_Nm")
            }
        )
        motor_sec.done()
        effects = {}
        eff_sec = sec.section("effects", required=False)
        for eff in eff_sec.keys():
            if eff not in EFFECTS:
                raise eff_sec.error(eff, f"unknown effect (known: {', '.join(EFFECTS)})")
            es = eff_sec.section(eff)
            values = {}
            for key, param in EFFECTS[eff].items():
                values[param] = (
                    es.get(key, str)
                    if key == "source"
                    else es.get(key, float, OPTIONAL.get(key, ...), low=RANGES[key][0], high=RANGES[key][1])
                )
            es.done()
            effects[eff] = values
        eff_sec.done()
        axes[name] = SimAxis(
            name=name,
            node_id=sec.get("node_id", int, low=1, high=127),
            serial=sec.get("serial", int, 0, low=0, high=2**32 - 1),
            J=plant.get("J", float, low=1e-9, high=10.0),
            c0=plant.get("c0", float, low=0.0, high=100.0),
            c1=plant.get("c1", float, low=0.0, high=100.0),
            cp=plant.get("cp", float, 0.0, low=-100.0, high=100.0),
            D=plant.get("D", float, 0.0, low=-100.0, high=100.0),
            torque_noise_Nm=sec.get("torque_noise_Nm", float, 0.0, low=0.0, high=10.0),
            motor=motor,
            effects=effects,
            brake=sec.get("brake", bool, True),
            end_stops_rad=_span(sec, "end_stops_rad"),
            initial_position_rad=sec.get("initial_position_rad", float, 0.0, low=-1e6, high=1e6),
            saved_limits=_saved_limits(sec),
        )
        plant.done()
        sec.done()
    axes_sec.done()
    top.done()
    for ax in axes.values():
        src = ax.effects.get("cross_axis", {}).get("CPL_SRC")
        if src is not None and src not in axes:
            raise axes_sec.error(f"{ax.name}.effects.cross_axis.source", f"no axis named {src!r}")
    ids = [a.node_id for a in axes.values()]
    if len(set(ids)) != len(ids):
        raise axes_sec.error("node_id", f"node ids must be unique, got {ids}")
    return SimConfig(axes=axes, seed=seed, path=path)
