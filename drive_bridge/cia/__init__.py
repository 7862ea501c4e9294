"""The protocol floor: the CANopen vocabulary and machinery that the master, the drive parameters
and the simulated drives share -- CiA 301's communication objects and error codes (:mod:`.p301`),
the CiA 402 drive profile's states, control and status words, modes and option codes
(:mod:`.p402`) and the objects that carry a setpoint (:mod:`.setpoint`), the object dictionary
from an EDS/DCF (:mod:`.od`, checked by :mod:`.edscheck`, written as a DCF by :mod:`.dcf`), the
factor group (:mod:`.factor`), one PDO codec (:mod:`.pdo`), objects read and written by SDO
(:mod:`.sdo`), and the bus opened (:mod:`.buses`, :mod:`.multicast`).  It imports python-can,
canopen and the package's leaves only; everything above stands on it."""
