"""
The analyzer's report as text: the JSON file and the verdict printed at the end.

Pure formatting of the report dict (see the README for its fields): nothing
here reads a recording, analyses or writes a file.
"""

import json
import math

import numpy as np

VERDICT_WORDS = {True: 'stiction', False: 'no stiction', None: 'cannot tell'}
FRICTION_WORDS = {'stiction': 'stiction claimed', 'backlash': 'backlash (play without stick)',
                  'none': 'not claimed'}


def _jsonable(x):
    """Return ``x`` with numpy scalars, tuples and non-finite floats made JSON-safe."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    return x


def to_json_text(report: dict) -> str:
    """Return the report as indented JSON (NaN written as null)."""
    return json.dumps(_jsonable(report), indent=2, ensure_ascii=False, allow_nan=False)


def summary_line(report: dict) -> str:
    """
    Return the verdict printed at the end of ``stiction-analyze``.

    Parameters
    ----------
    report : dict
        The report of one recording (``Analysis.report``).

    Returns
    -------
    str
        One line with the verdict and the fits, then indented evidence and,
        after ``--explain``, the located and named mismatch, one per line.

    """
    st = report['stiction']
    word = VERDICT_WORDS[st['detected']]
    fits = '; '.join(f'{f["model"]} S={f["S"]:.2f} J={f["J"]:.2f} MSE={f["mse"]:.4g}'
                     for f in report['fits'])
    if st.get('probability') is not None:
        how = f'probability {st["probability"]:.2f}'
    elif st['detected'] is None:
        how = st.get('reason', '')
    else:
        how = f'score {st["score"]:.2f}'
    line = (f'{report.get("name") or report["input"].get("path")}: {word} ({how})'
            + (f'; {fits}' if fits else ''))
    for ev in st.get('evidence', [])[:2]:
        line += f'\n  evidence: {ev}'
    if st.get('size_withheld'):
        line += f'\n  no size given: {st["size_withheld"]}'
    if 'mismatch' in report and 'baseline' not in report:
        line += f'\nmismatch: cannot tell: {report["mismatch"]["explanation"]}'
    elif 'mismatch' in report:
        line += _mismatch_lines(report)
    return line


def _mismatch_lines(report):
    m, b = report['mismatch'], report['baseline']
    line = f'\nplain model: kano S={b["S"]:.3f} J={b["J"]:.3f} MSE fit {b["mse_fit"]:.4g}'
    if m.get('regimes'):
        r = m['regimes'][0]
        line += (f'\nlocated: {r["regime"]} holds {100 * r["residual_share"]:.0f} % of the '
                 f'residual in {100 * r["sample_share"]:.0f} % of the samples')
    if m.get('regions'):
        g = m['regions'][0]
        line += (f'; worst stretch t={g["t_start"]:.0f}-{g["t_end"]:.0f} s ({g["regime"]}, '
                 f'{100 * g["residual_share"]:.0f} % of the residual)')
    line += _chain_lines(report)
    names = [e['id'] for e in m.get('effects', [])]
    told = ' '.join(e['sentence'] for e in m['effects']) if names else m['explanation']
    line += (f'\nmismatch: {", ".join(names) or m["effect"]} (confidence '
             f'{m["confidence"]:.2f}): {told}\nheld-out MSE: plain '
             f'{b["mse_holdout"]:.4g} -> explained {m["mse_holdout"]:.4g}')
    if m.get('note'):
        line += f'\nnote: {m["note"]}'
    if report['stiction'].get('detected') and m.get('friction') is False:
        line += ('\nnote: the stiction verdict above comes from valve models without dead '
                 'time or calibration; no friction beats the best valve without friction '
                 'here')
    return line


def _chain_lines(report):
    f = report.get('frictionless')
    if not f:
        return ''
    kind = report['mismatch'].get('friction_kind', 'none')
    return (f'\nbest valve without friction: dead time {f["dead_time_s"]:.3g} s, lag '
            f'{f["lag_s"]:.3g} s, offset {f["offset"]:+.3g} %, gain {f["gain"]:.4g} (stages '
            f'kept: {", ".join(f["stages"]) or "none"}), held-out MSE {f["mse_holdout"]:.4g}'
            f'\nfriction: {FRICTION_WORDS[kind]}')


def batch_row_text(row: dict) -> str:
    """Return the lines printed for one recording of a batch (its summary, or its error)."""
    if not row['ok']:
        return f'{row["input"]}: error: {row["error"]}'
    # Recordings often share a tag name; the path tells them apart.
    first, *rest = row['summary'].split('\n')
    return '\n'.join([f'{row["input"]}: {first.split(": ", 1)[-1]}', *rest])
