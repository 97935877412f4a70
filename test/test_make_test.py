"""``make test`` runs every test: its last run names the files that hold an ``alone`` test."""

from pathlib import Path
import re

ROOT = Path(__file__).resolve().parents[1]


def test_the_alone_run_names_every_file_that_holds_an_alone_test():
    named = re.search(r'^ALONE_TESTS := (.*)$', (ROOT / 'Makefile').read_text(), re.M)
    assert named, 'the Makefile names the alone files in ALONE_TESTS'
    marked = sorted(str(p.relative_to(ROOT)) for p in (ROOT / 'test').glob('test_*.py')
                    if p.name != Path(__file__).name and 'mark.alone' in p.read_text())
    assert marked and sorted(named.group(1).split()) == marked
