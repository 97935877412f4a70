"""
The sentence that says which part of a record's valid samples OP and PV were judged on.

Gaps cut a record into stretches: the detector pools the ones it can judge,
the signatures and the size read the longest, and stretches under
``MIN_SIGNATURE_SAMPLES`` are read by nothing.  The terminal's ``judged:``
line and the HTML page say the same sentence, written here from the report's
JSON.
"""

from stiction_ros.analysis.pipeline import MIN_SIGNATURE_SAMPLES as MIN_STRETCH


def judged_text(report: dict) -> str:
    """Return what part of the valid samples OP and PV were judged on, if notably less."""
    win = report.get('signature_window')
    # With MV the fits decide, and they run on across gaps.
    if report.get('fits') or not win:
        return ''
    text = _judged(report, win)
    short = report.get('short_stretches') or {}
    if short.get('valid_samples'):
        k = short['stretches']
        text = (text + '; ' if text else '') + (
            f'{short["valid_samples"]} valid samples in {k} stretch{"es" if k > 1 else ""} '
            f'under {MIN_STRETCH} samples between gaps were not read')
    return text


def _judged(report: dict, win: dict) -> str:
    valid = report.get('valid_samples') or 0
    parts = ((report.get('stiction') or {}).get('detector') or {}).get('stretches') or []
    judged = [t for t in parts if t.get('probability') is not None]
    longest = (f'{win["samples"]} samples ({win["start_s"]:g}-{win["end_s"]:g} s)')
    if len(judged) > 1:
        # The detector pooled the stretches; the signatures and the size read one.
        return (f'the detector pooled {len(judged)} stretches between gaps '
                f'({sum(t["samples"] for t in judged)} of {valid} valid samples); the '
                f'signatures read the longest, {longest}')
    if judged and parts[0].get('probability') is None:
        t = judged[0]
        return (f'the detector judged {t["samples"]} of {valid} valid samples '
                f'({t["start_s"]:g}-{t["end_s"]:g} s) alone: the longest stretch, {longest}, '
                f'could not be judged ({_code(parts[0])}); the signatures read it')
    if win['samples'] >= 0.9 * valid:
        return ''
    # Gaps split the record and the signatures and the detector read one stretch.
    text = (f'OP and PV on their longest valid stretch only, {win["samples"]} of {valid} valid '
            f'samples ({win["start_s"]:g}-{win["end_s"]:g} s); gaps split the rest')
    others = [_code(t) for t in parts[1:] if t.get('probability') is None]
    if others:
        text += (f', and {len(others)} other stretch{"es" if len(others) > 1 else ""} of '
                 f'{MIN_STRETCH} samples or more could not be judged alone '
                 f'({", ".join(sorted(set(others)))})')
    return text


def _code(stretch: dict) -> str:
    return (stretch.get('not_judged') or 'not judged').replace('_', ' ')
