"""CiA 301 vocabulary: NMT states, the SYNC COB-ID and the emergency error codes drive-bridge
reads (CiA 301's communication codes with CiA 402's drive codes), worded for a person."""

from __future__ import annotations

#: NMT states as a heartbeat carries them
NMT_STOPPED, NMT_OPERATIONAL, NMT_PREOP = 0x04, 0x05, 0x7F
SYNC_COB_ID = 0x080
SYNC_PRODUCER = 1 << 30  # COB-ID SYNC (0x1005) bit 30: this node produces SYNC
MAX_SYNC_COUNTER = 240  # the SYNC counter's largest overflow value (0x1019)

ERR_FOLLOWING = 0x8611  # CiA 402: following error
ERR_RPDO_TIMEOUT = 0x8250  # RPDO timeout: the master's setpoints stopped
ERR_HEARTBEAT = 0x8130  # heartbeat consumer: a watched node fell silent (life guard error)
ERR_PDO_LENGTH = 0x8210  # PDO not processed: shorter than its mapping
ERR_SYNC_LENGTH = 0x8240  # a SYNC of another length than the consumer's 0x1019 says (a counter or none)
ERR_PARAMETER = 0x6320  # a value the device cannot take (parameter error)
ERR_SOFTWARE = 0x6100  # internal software
#: the codes a drive sends when its master went silent
MASTER_LOSS = {ERR_RPDO_TIMEOUT, ERR_HEARTBEAT}

EMCY_TEXT = {
    ERR_FOLLOWING: "following error",
    ERR_RPDO_TIMEOUT: "RPDO timeout (loss of setpoint)",
    ERR_HEARTBEAT: "heartbeat or life guard error",
    ERR_PDO_LENGTH: "PDO not processed (length error)",
    ERR_SYNC_LENGTH: "unexpected SYNC data length (the SYNC counter 0x1019 differs between nodes)",
    ERR_PARAMETER: "parameter error (a value the drive cannot take)",
    ERR_SOFTWARE: "internal software error",
    0x8400: "velocity speed controller",
    0x2310: "continuous over-current",
    0x3210: "DC link over-voltage",
    0x4310: "drive temperature",
}


def emcy_text(code: int) -> str:
    """An emergency error code in words (its number where drive-bridge has none).

    Parameters
    ----------
    code : int
        The EMCY error code.

    Returns
    -------
    str
        Its text.
    """
    return EMCY_TEXT.get(code, f"EMCY 0x{code:04X}")
