"""The batch summary's tally: why each `cannot tell` got no answer, from any row it is given."""

from stiction_ros.app.batch import _why_not, Batch
from stiction_ros.cli.analyze import print_many


def _row(detected, why=None):
    row = {'input': 'r.txt', 'ok': True, 'detected': detected,
           'summary': 'TAG: cannot tell' if detected is None else 'TAG: stiction'}
    if why is not None:
        row['why_not'] = why
    return row


def test_why_not_names_balanced_evidence_or_the_check_failed():
    assert _why_not({'detector': {'balanced': True, 'judgeable': {'ok': True, 'code': ''}},
                     'reason': 'the evidence is balanced'}) == 'evidence balanced'
    assert _why_not({'detector': {'judgeable': {'ok': False, 'code': 'not_in_control'}},
                     'reason': 'not in control: ...'}) == 'not in control'
    # Nothing named by the detector: the reason's first words, not a bare "other".
    assert _why_not({'reason': 'too few fits: the valve position is missing'}) == \
        'too few fits'
    assert _why_not({}) == 'no reason given'
    # With MV: a band whose slip jump may be none, named, not cut from its sentence.
    assert _why_not({'cannot_tell': 'slip_unresolved',
                     'reason': 'a band of 3 % whose slip jump cannot be told from none: J = '
                               '0.20 % (95 % range 0.02-0.40) ...'}) == 'slip jump unresolved'
    assert _why_not({'cannot_tell': 'noisy_mv', 'reason': 'stick-slip (S = 3 %, ...'}) == \
        'MV noise'
    # A valve without friction fits as well, or neither it nor stick-slip explains MV.
    assert _why_not({'cannot_tell': 'frictionless_fits',
                     'reason': 'stick-slip fits MV with MSE 0.3 ...'}) == \
        'frictionless valve fits'
    assert _why_not({'cannot_tell': 'unexplained_mv', 'reason': 'neither stick-slip ...'}) == \
        'MV unexplained'
    assert _why_not({'cannot_tell': 'few_slips',
                     'reason': 'the fitted valve starts to move 0 times ...'}) == 'too few slips'


def test_the_tally_breaks_cannot_tell_down_and_survives_rows_without_a_reason(capsys):
    rows = [_row(True), _row(None, 'evidence balanced'), _row(None, 'too short'),
            _row(None, 'evidence balanced'), _row(None)]
    batch = Batch('d', rows, 1.0, '1 process(es)')
    assert batch.tally() == {'stiction': 1, 'cannot tell': 4}
    assert batch.why_not() == {'evidence balanced': 2, 'too short': 1, 'reason not given': 1}
    assert print_many(batch) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert ('4 cannot tell (2 evidence balanced, 1 reason not given, 1 too short), '
            '1 stiction') in last
