"""What an engineer reads about each instrument or actuator effect: id, size, error, sentence."""

import math

# The effects of the chain around the friction model, beside EFFECTS.md's friction ones.
INSTRUMENT_IDS = ('dead_time', 'response_lag', 'positioner_calibration', 'rate_limit',
                  'travel_limits', 'backlash', 'quantisation')


def _fmt(v: float) -> str:
    return f'{v:.2g}' if abs(v) < 10 else f'{v:.0f}'


def _pm(se: float | None, scale: float = 1.0) -> str:
    if se is None or not math.isfinite(se):
        return ''
    return f' +- {_fmt(se * scale)}'


def chain_effects(fit, se: dict, sample_time: float, quantum: float = 0.0) -> list:
    """
    Return the effects a fitted chain keeps, each with size, unit, uncertainty and sentence.

    ``se`` holds the standard error of each free stage (samples for the
    timing stages, % or ratio for calibration); ``quantum`` is the reading's
    resolution when it reads in steps (0 when continuous).
    """
    p, out = fit.params, []
    ts = sample_time
    if 'delay' in fit.free:
        d = p['delay'] * ts
        err = se.get('delay')
        out.append({
            'id': 'dead_time', 'size': round(d, 4), 'unit': 's',
            'uncertainty': None if err is None else round(err * ts, 4),
            'sentence': (f'The position follows OP {_fmt(d)}{_pm(err, ts)} s late '
                         f'({p["delay"]:.2f} samples): dead time in the positioner or the '
                         'transmitter, or OP and MV stamped on different clocks.'),
            'params': {'dead_time_s': d}})
    # A lag after stiction is left to the friction effects (EFFECTS.md's measurement lag).
    if 'tau' in fit.free and fit.friction != 'stiction':
        tau, tau2 = p['tau'] * ts, p['tau2'] * ts if 'tau2' in fit.free else 0.0
        err = se.get('tau')
        second = f' and a second lag of {_fmt(tau2)} s' if tau2 > 0 else ''
        out.append({
            'id': 'response_lag', 'size': round(tau, 4), 'unit': 's',
            'uncertainty': None if err is None else round(err * ts, 4),
            'sentence': (f'The position follows OP through a first-order lag of '
                         f'{_fmt(tau)}{_pm(err, ts)} s{second}: a slow actuator or a '
                         'filtered position transmitter (from OP and MV alone the two look '
                         'the same).'),
            'params': {'lag_s': tau, 'lag2_s': tau2}})
    if 'offset' in fit.free or 'gain' in fit.free:
        off, gain = p['offset'], p['gain']
        out.append({
            'id': 'positioner_calibration', 'size': round(off, 4), 'unit': '%',
            'uncertainty': None if se.get('offset') is None else round(se['offset'], 4),
            'sentence': (f'The reading is {off:+.2g}{_pm(se.get("offset"))} % off and '
                         f'scaled by {gain:.3f}{_pm(se.get("gain"))}: at 50 % OP the valve '
                         f'reads {off + 50.0 * gain:.1f} %; recalibrate the positioner or '
                         'the position transmitter.'),
            'params': {'offset': off, 'gain': gain}})
    if 'rate' in fit.free and p.get('rate', 0.0) > 0.0:
        rate, err = p['rate'] / ts, se.get('rate')
        out.append({
            'id': 'rate_limit', 'size': round(rate, 4), 'unit': '%/s',
            'uncertainty': None if err is None else round(err / ts, 4),
            'sentence': (f'The valve moves no faster than {_fmt(rate)}{_pm(err, 1.0 / ts)} %/s: '
                         'OP steps become ramps (actuator air supply, booster or motor speed); '
                         'no friction is needed for that.'),
            'params': {'rate_pct_s': rate}})
    if 'travel' in fit.free and p.get('travel', 0.0) > 0.0:
        lo, hi = p['travel_lo'], p['travel_hi']
        where = ' and '.join(f'{w} {v:.3g} %' for w, v in (('below', hi), ('above', lo))
                             if math.isfinite(v))
        out.append({
            'id': 'travel_limits', 'size': round(hi if math.isfinite(hi) else lo, 4),
            'unit': '%', 'uncertainty': None,
            'sentence': (f'The reading stays {where} while OP goes on: '
                         'the valve is on a travel stop (or the positioner range is set '
                         'narrower than the OP range).'),
            'params': {'travel_lo': lo, 'travel_hi': hi}})
    if fit.friction == 'backlash':
        out.append({
            'id': 'backlash', 'size': round(fit.S, 4), 'unit': '%', 'uncertainty': None,
            'sentence': (f'Play of {_fmt(fit.S)} % without stick: after each reversal OP '
                         'must take up the play before the valve moves, then it moves '
                         'smoothly with no slip jump: a worn linkage, loose positioner '
                         'feedback, a deadband set in the positioner or a low positioner '
                         'gain, or friction whose static and kinetic forces are equal '
                         "(the chapter's pure deadband, J = 0), which OP and MV cannot tell "
                         'apart; not stick-slip.'),
            'params': {'backlash': fit.S}})
    if quantum > 0.0:
        out.append({
            'id': 'quantisation', 'size': round(quantum, 5), 'unit': '%',
            'uncertainty': None,
            'sentence': (f'The position reading moves in steps of {quantum:.3g} %: the '
                         'transmitter resolution; a residual of '
                         f'{quantum / math.sqrt(12.0):.2g} % RMS is the steps, not physics.'),
            'params': {'quantum': quantum}})
    return out


def explained_size(report: dict) -> tuple[str, float, float] | None:
    """
    Return (model name, S, J) of the explained friction model of a report, or None.

    After ``--explain`` names an effect, the size of the model with that
    physics in place is the valve's own; the fits' size is the plain model's.
    """
    m = report.get('mismatch') or {}
    model = m.get('model') or {}
    params = model.get('params') or {}
    found = m.get('effect') not in (None, 'none', 'unexplained')
    if found and str(model.get('name', '')).startswith('kano+') and 'S' in params \
            and 'J' in params:
        return str(model['name']), float(params['S']), float(params['J'])
    return None
