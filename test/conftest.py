"""Test-wide settings: DDS stays on this machine, each run on its own domain."""

import os

import pytest

# Set before any test imports rclpy, and inherited by every node process the
# tests start: discovery only on 127.0.0.1, and a domain of our own so that
# parallel runs on the same machine do not see each other.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(1 + os.getpid() % 100))
os.environ.setdefault('MPLBACKEND', 'Agg')


@pytest.fixture(scope='module')
def probe(request):
    """Return an rclpy node of the test module's own, spinning in a thread."""
    # Imported here: most tests must run, and some must prove they run, without rclpy.
    import rclpy
    from ros_helpers import Probe
    if not rclpy.ok():
        rclpy.init()
    p = Probe(request.module.__name__.rsplit('.', 1)[-1] + '_probe')
    yield p
    p.close()
    rclpy.try_shutdown()


@pytest.fixture(scope='session')
def report_pages(tmp_path_factory):
    """Return the three report pages of report_pages.py, written once per session."""
    from report_pages import write_pages
    return write_pages(tmp_path_factory.mktemp('report_pages'))


def pytest_terminal_summary(terminalreporter):
    """Say how many inputs the fuzz suite tried, and how each ended."""
    import sys
    fuzz = sys.modules.get('test_fuzz_inputs')
    if fuzz is None or not fuzz.TRIED:
        return
    total = sum(fuzz.TRIED.values())
    terminalreporter.write_line(f'fuzz: {total} inputs tried')
    for kind, n in sorted(fuzz.TRIED.items()):
        ends = ', '.join(f'{fuzz.OUTCOMES[f"{kind}: {how}"]} {how}s'
                         for how in ('result', 'one-line error'))
        terminalreporter.write_line(f'  {kind}: {n} ({ends})')
