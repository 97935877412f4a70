"""The --explain benchmark's table: confusion matrix, false alarms and MSE ratios from rows."""

from bench.explain_bench import case_list, markdown
from stiction_ros.sim.concealed_cases import FAMILIES, SIZES


def row(family, effect, found, ratio, seed=0):
    return {'family': family, 'effect': effect, 'seed': seed, 'noise': 1.0, 'found': found,
            'confidence': 0.9, 'baseline_holdout': 0.2, 'explained_holdout': 0.2 * ratio,
            'ratio': ratio, 'explain_s': 10.0}


def test_case_list_covers_every_effect_at_several_noise_levels():
    cases = case_list(5, 5)
    kano = [c for c in cases if c['family'] == 'kano']
    physical = [c for c in cases if c['family'] == 'physical']
    assert {c['effect'] for c in kano} == set(SIZES) and len(kano) == 5 * len(SIZES)
    assert {c['effect'] for c in physical} == set(FAMILIES['physical'])
    for effect in SIZES:
        assert len({c['noise'] for c in kano if c['effect'] == effect}) == 3
    assert len({(c['family'], c['seed']) for c in cases}) == len(cases)


def test_markdown_counts_hits_misses_and_false_alarms():
    rows = [row('kano', 'none', 'none', 1.0, 1), row('kano', 'none', 'actuator_lag', 0.98, 2),
            row('kano', 'actuator_lag', 'actuator_lag', 0.1, 3),
            row('kano', 'actuator_lag', 'measurement_lag', 0.3, 4),
            row('kano', 'actuator_lag', 'actuator_lag', 0.2, 5)]
    text = markdown(rows, 60.0, 2, 3)
    assert '| `actuator_lag` | **2** | 1 | . |' in text
    assert '| `none` | 1 | . | **1** |' in text
    assert 'False alarms on `none`: 1/2' in text
    assert 'Effects named correctly where one is hidden: 2/3 (67 %' in text
    # Median held-out ratio over the three actuator-lag cases: 0.2.
    assert '| kano | `actuator_lag` | 3 | 0.200 | 0.300 |' in text
