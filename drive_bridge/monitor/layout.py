"""What a listener needs to read a running machine's PDOs: per axis the TPDOs (and the RPDOs
that carry its setpoints) as bus.yml maps them -- the mapping ``export`` writes into the DCFs a
production master loads -- and the units to read them in, all without sending a frame."""

from __future__ import annotations

from dataclasses import dataclass

from ..cia.objects import POSITION_ACTUAL, torque_object
from ..cia.pdo import PdoCodec
from ..cia.setpoint import SETPOINT_OBJECTS
from ..config import BusConfig, NodeConfig, PdoConfig
from ..errors import UserError
from ..units import Scaling

POSITION = POSITION_ACTUAL


def _codecs(ncfg: NodeConfig, pdos: tuple[PdoConfig, ...], base: int) -> list[PdoCodec]:
    """The codecs of ``pdos`` with the COB-IDs bus.yml gives them (the predefined set where none)."""
    return [
        PdoCodec.of(p.cob_id or base + 0x100 * (p.number - 1) + ncfg.node_id, ncfg.od, p.mapping)
        for p in pdos
    ]


@dataclass
class Layout:
    """The PDOs of every axis a listener decodes, their units and the SYNC period.

    Parameters
    ----------
    tpdos, rpdos : dict of str to list of PdoCodec
        Per axis, its PDOs.
    scaling : dict of str to Scaling
        Per axis, its units.
    period : float
        The SYNC period [s].
    moving_rad_s : dict of str to float
        Per axis, the speed [rad/s] above which it is taken to be moving.
    """

    tpdos: dict[str, list[PdoCodec]]
    rpdos: dict[str, list[PdoCodec]]
    scaling: dict[str, Scaling]
    period: float
    moving_rad_s: dict[str, float]

    @classmethod
    def of(cls, config: BusConfig) -> Layout:
        """The layout of a bus configuration's axes.

        Parameters
        ----------
        config : BusConfig
            The bus configuration.

        Returns
        -------
        Layout
            The layout.

        Raises
        ------
        UserError
            Naming the axis where listening alone cannot read it: the units are the drive's own
            (``from_drive``, read by SDO), or a TPDO lacks the position or the torque.
        """
        tpdos, rpdos, scaling, moving = {}, {}, {}, {}
        for axis, ncfg in config.nodes.items():
            where = f"{config.path}: nodes.{axis}"
            sc = ncfg.scaling
            if ncfg.units_from_drive or not sc.increments_per_rev > 0:
                raise UserError(
                    f"{where}.scaling: the units are the drive's own (from_drive), read by SDO at "
                    f"bring-up; monitor never sends a frame: give increments_per_rev (and "
                    f"velocity_unit) in bus.yml, or run 'drive-bridge export' after a commissioning"
                )
            if not sc.rated_torque_Nm > 0:
                raise UserError(
                    f"{where}.scaling.rated_torque_Nm: missing (read from the drive's 0x6076 at "
                    f"bring-up; monitor never sends a frame): give it in bus.yml"
                )
            tpdos[axis] = _codecs(ncfg, ncfg.tpdo, 0x180)
            mapped = {i for c in tpdos[axis] for i in c.objects}
            for index, what in (
                (POSITION, "position 0x6064"),
                (torque_object(sc.torque_feedback, sc.torque_index), "torque"),
            ):
                if index not in mapped:
                    raise UserError(
                        f"{where}.tpdo: no TPDO maps the {what} (0x{index:04X}); monitor identifies "
                        f"from what the drives publish: map it as the production master does"
                    )
            rpdos[axis] = [
                c
                for c in _codecs(ncfg, ncfg.rpdo, 0x200)
                if any(entry in SETPOINT_OBJECTS for entry in c.entries)
            ]
            scaling[axis] = sc
            lim = ncfg.limits
            moving[axis] = max(0.01 * lim.max_velocity, 0.05) if lim.max_velocity > 0 else 0.1
        return cls(tpdos, rpdos, scaling, config.master.sync_period_s, moving)

    @property
    def cob_ids(self) -> set[int]:
        """The COB-IDs of every PDO it decodes."""
        return {c.cob_id for codecs in (*self.tpdos.values(), *self.rpdos.values()) for c in codecs}
