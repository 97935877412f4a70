"""Where each constant and state entry of the physical valve lives in the kernels' arrays."""

# Indices into the constants array handed to the kernels.
_M, _K, _A, _F0, _XMAX, _PMIN, _DP, _TAU, _FC, _FS, _FV, _VS, _TS, _VSTICK = range(14)
_DT, _EP, _NSUB, _STRIB, _DFS, _GAMMA, _ASYM, _FOH, _NCONST = range(14, 23)

# Indices into the state array; state[0] is the output, as base.py requires.
# S_REST: seconds the stem has been at rest (for the dwell-time static friction);
# S_UPREV: the previous input, which a first-order hold ramps from.
S_Y, S_X, S_V, S_P, S_STUCK, S_DIR, S_SIGNWAIT, S_REST, S_UPREV = range(9)
STATE_SIZE = 9
