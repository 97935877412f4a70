"""Where the tests find the shared data that live beside the checkout."""

from pathlib import Path


def plant_loops_dir():
    """Return the labelled plant loops folder (``../shared/data/plant_loops``), or None."""
    here = Path(__file__).resolve().parents[1]
    for base in (here.parent / 'shared', Path('/work/shared')):
        d = base / 'data' / 'plant_loops'
        if d.is_dir():
            return d
    return None
