"""The protocol floor: the CANopen vocabulary that the master, the drive parameters and the
simulated drives share -- CiA 301's communication objects and error codes (:mod:`.p301`) and the
CiA 402 drive profile's states, control and status words, modes and option codes (:mod:`.p402`).
It imports python-can and canopen only; everything above stands on it."""
