"""The fields of one profile fit, compiled: the last axis of the candidate table.

The same indices as :mod:`slitcli.laser.profile`'s ``F_*`` constants (the Python side
keeps them; tests/test_laser_kernels.py checks that the two agree), as compile-time
constants for the kernels that read the table.
"""

cdef enum:
    F_POS = 0
    F_AMP = 1
    F_WIDTH = 2
    F_Z = 3
    F_SE_POS = 4
    F_CHI2 = 5
    F_SAT = 6       # 0 unclipped, 1 a clipped core, 2 a white one (every channel)
    F_NOISE = 7
    F_TR = 8
    F_TG = 9
    F_TB = 10
    F_KR = 11
    F_KG = 12
    F_KB = 13
    F_NCORE = 14
    F_FLAT = 15
    F_GNOISE = 16
    N_FIELDS = 17
