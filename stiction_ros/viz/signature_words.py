"""What each stiction signature's value measures, its unit, and which way its threshold points."""

# Shared by the signatures' figure and the HTML page's table, so the two say the same.
SIGNATURES = {
    'horch': ('phase |dphi| of the OP-PV cross-correlation', 'deg', '\u2265'),
    'he_curve_fit': ('stiction index SI (sine vs triangle fit)', '', '\u2265'),
    'bicoherence': ('non-linearity index NLI', '', '>'),
    'ellipse': ('apparent stiction (PV-OP ellipse width)', '% of OP', '\u2265'),
    'hos_pv_op': ('apparent stiction, if the loop is non-linear', '% of OP', '\u2265'),
    'yamashita': ('share of samples where OP moved and PV stayed', '', '>'),
    'slip_events': ('slip events', '', '\u2265'),
}
