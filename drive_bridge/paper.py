"""What this project takes from Aggogeri et al. 2019, "Experimental Identification of the Dynamics
Model for Cartesian Robot": the identified plant (Table II) and the gain scenarios (Table III),
motor side, SI."""

#: Table II: inertia J [kg·m²], Coulomb c0 [Nm] and viscous c1 [Nm·s/rad] friction per axis
TABLE_II = {
    "x": {"J": 0.000089, "c0": 0.2198, "c1": 0.000312},
    "y": {"J": 0.000100, "c0": 0.3230, "c1": 0.000500},
    "z": {"J": 0.000100, "c0": 0.3230, "c1": 0.000500},
}

#: Table III: the gain scenarios (KpP 1/s, KpS Nm·s/rad, KiS 1/s), model feed-forward off
TABLE_III = {
    "scenario 1": {"KpP": 150.0, "KpS": 0.12, "KiS": 20.0, "FwF": 1.0, "ff_enable": 0.0},
    "scenario 2": {"KpP": 170.0, "KpS": 0.17, "KiS": 15.0, "FwF": 0.5, "ff_enable": 0.0},
    "scenario 3": {"KpP": 200.0, "KpS": 0.30, "KiS": 17.0, "FwF": 1.0, "ff_enable": 0.0},
}
