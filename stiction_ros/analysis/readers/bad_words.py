"""The words historians and spreadsheets write in a cell whose value they do not have."""

# What historians (OSIsoft PI's system digital states, IP.21, PHD) and Excel write in
# place of a value they do not have: a bad value, never a number.  A lone '-' is not
# one: Excel's accounting format writes a zero so (a shut valve's OP).
BAD_WORDS = frozenset([
    'no data', 'bad', 'bad input', 'bad data', 'bad quality', 'i/o timeout', 'shutdown',
    'comm fail', 'scan off', 'out of serv', 'calc failed', 'pt created', 'configure',
    'over range', 'under range', 'intf shut', 'no sample', 'no good data', 'null', 'none',
    'n/a', '#n/a', '#value!', '#div/0!', '#ref!', '#num!', '#name?', '#null!', '<null>',
    '--', '---', '?'])
