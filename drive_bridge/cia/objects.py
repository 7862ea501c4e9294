"""The CiA 301 and CiA 402 objects drive-bridge reads, writes, maps or simulates, each named once:
the one place their numbers stand (issue 69).  Names follow the standards' own ("Controlword",
"Position actual value"); the bits and values an object holds are named in :mod:`.p301` and
:mod:`.p402`, the factor group's units in :mod:`.factor`.  A vendor's own objects (0x2000-0x5FFF)
are named in that vendor's module."""

from __future__ import annotations

# -- CiA 301: communication ------------------------------------------------------------------------
DEVICE_TYPE = 0x1000
ERROR_REGISTER = 0x1001
ERROR_FIELD = 0x1003  # pre-defined error field: the error history
COB_ID_SYNC = 0x1005  # bit 30: this node produces SYNC
CYCLE_PERIOD = 0x1006  # communication cycle period [µs]
STORE_PARAMETERS = 0x1010
RESTORE_DEFAULTS = 0x1011
HEARTBEAT_CONSUMER = 0x1016
HEARTBEAT_PRODUCER = 0x1017
IDENTITY_OBJECT = 0x1018  # sub 1 vendor id, 2 product code, 3 revision number, 4 serial number
SYNC_COUNTER_OVERFLOW = 0x1019  # the SYNC counter's largest value (0: no counter)
RPDO_COMMUNICATION = 0x1400  # the first RPDO's communication parameters (one object per PDO from here)
RPDO_MAPPING = 0x1600
TPDO_COMMUNICATION = 0x1800
TPDO_MAPPING = 0x1A00
PDO_PARAMETERS_END = 0x1BFF  # the last object of the PDO parameter range

# -- CiA 402: the drive --------------------------------------------------------------------------
ABORT_CONNECTION_OPTION = 0x6007
ERROR_CODE = 0x603F
CONTROLWORD = 0x6040
STATUSWORD = 0x6041
QUICK_STOP_OPTION = 0x605A
FAULT_REACTION_OPTION = 0x605E
MODES_OF_OPERATION = 0x6060
MODES_OF_OPERATION_DISPLAY = 0x6061
POSITION_ACTUAL = 0x6064
FOLLOWING_ERROR_WINDOW = 0x6065
FOLLOWING_ERROR_TIMEOUT = 0x6066
POSITION_WINDOW = 0x6067
POSITION_WINDOW_TIME = 0x6068
VELOCITY_ACTUAL = 0x606C
VELOCITY_WINDOW = 0x606D
VELOCITY_WINDOW_TIME = 0x606E
VELOCITY_THRESHOLD = 0x606F
VELOCITY_THRESHOLD_TIME = 0x6070
TARGET_TORQUE = 0x6071
MAX_TORQUE = 0x6072
MOTOR_RATED_CURRENT = 0x6075
MOTOR_RATED_TORQUE = 0x6076
TORQUE_ACTUAL = 0x6077
CURRENT_ACTUAL = 0x6078
TARGET_POSITION = 0x607A
HOME_OFFSET = 0x607C
SOFTWARE_POSITION_LIMIT = 0x607D  # sub 1 minimum, 2 maximum
MAX_PROFILE_VELOCITY = 0x607F
MAX_MOTOR_SPEED = 0x6080
PROFILE_VELOCITY = 0x6081
PROFILE_ACCELERATION = 0x6083
PROFILE_DECELERATION = 0x6084
QUICK_STOP_DECELERATION = 0x6085
POSITION_ENCODER_RESOLUTION = 0x608F
GEAR_RATIO = 0x6091
FEED_CONSTANT = 0x6092
HOMING_METHOD = 0x6098
HOMING_SPEEDS = 0x6099  # sub 1 toward the switch, 2 toward zero
HOMING_ACCELERATION = 0x609A
POSITION_DIMENSION = 0x60A8  # SI unit of position
VELOCITY_DIMENSION = 0x60A9  # SI unit of velocity
VELOCITY_OFFSET = 0x60B1
TORQUE_OFFSET = 0x60B2
INTERPOLATION_SUB_MODE = 0x60C0
INTERPOLATION_DATA_RECORD = 0x60C1
INTERPOLATION_TIME_PERIOD = 0x60C2  # sub 1 value, 2 index (the power of ten)
INTERPOLATION_DATA_CONFIGURATION = 0x60C4
#: its sub-indices: the records it holds at most, the records it holds now (the project drive's
#: fill; CiA 402's "actual buffer size"), 0 FIFO / 1 ring, 0 clears and disables / 1 enables access
BUFFER_MAXIMUM, BUFFER_FILL, BUFFER_ORGANISATION, BUFFER_CLEAR = 1, 2, 3, 6
MAX_ACCELERATION = 0x60C5
MAX_DECELERATION = 0x60C6
FOLLOWING_ERROR_ACTUAL = 0x60F4
TARGET_VELOCITY = 0x60FF
SUPPORTED_DRIVE_MODES = 0x6502


def torque_object(feedback: str, vendor_index: int | None = None) -> int:
    """The object an axis's torque is read from: torque actual for ``feedback`` "torque", current
    actual for "current", the vendor's ``vendor_index`` for "object".

    Parameters
    ----------
    feedback : {"torque", "current", "object"}
        :attr:`drive_bridge.units.Scaling.torque_feedback`.
    vendor_index : int, optional
        :attr:`drive_bridge.units.Scaling.torque_index`.

    Returns
    -------
    int
        The object's index.
    """
    if feedback == "object" and vendor_index is not None:
        return vendor_index
    return CURRENT_ACTUAL if feedback == "current" else TORQUE_ACTUAL
