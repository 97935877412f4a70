"""Published stiction signatures computed from OP and PV alone (no valve position)."""
