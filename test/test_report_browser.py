"""
The HTML report in a real browser: nothing loads from outside, every image shows, no errors.

The three real pages of report_pages.py (written by ``stiction-analyze ...
--html``, two with --explain, one without MV), shared with
test_report_html.py, are opened in headless Chromium through playwright.
Every request the page
issues is routed: the page itself and the PNGs beside it go on, anything else
is aborted and named, so nothing leaves the machine.  Where Chromium or
playwright is missing the module is skipped.
"""

from collections.abc import Iterator
import os
from pathlib import Path
import shutil
from urllib.parse import urlsplit
from urllib.request import url2pathname

import pytest


def find_chromium() -> str | None:
    """Return the Chromium to drive: Debian's, else the first on PATH, else None."""
    if os.access('/usr/bin/chromium', os.X_OK):
        return '/usr/bin/chromium'
    return shutil.which('chromium')


CHROMIUM = find_chromium()
if CHROMIUM is None:
    pytest.skip('no Chromium to open the HTML report in: install the Debian packages '
                'chromium and chromium-common (apt-get install chromium)',
                allow_module_level=True)
sync_api = pytest.importorskip(
    'playwright.sync_api',
    reason='playwright is not installed (requirements/test.txt has it; tools/bootstrap.sh)')

# What this machine's Chromium needs to start headless under a test runner, and no
# traffic of its own (updates, sync, QUIC).  Playwright adds a fresh temporary profile
# (user-data-dir) and removes it on close.  Should anything get past the route below,
# no host name resolves.
ARGS = ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
        '--disable-background-networking', '--disable-component-update', '--disable-sync',
        '--host-resolver-rules=MAP * ~NOTFOUND']
# Every <img> of the page, as the browser holds it once the page has loaded.
IMAGES = ('() => Array.from(document.images, (img) => ({alt: img.alt, '
          'src: img.currentSrc || img.src, complete: img.complete, '
          'width: img.naturalWidth, height: img.naturalHeight}))')


def short(url: str) -> str:
    """Return ``url`` cut to a readable length: data: URIs run to megabytes."""
    return url if len(url) <= 80 else url[:77] + '...'


def is_own(url: str, page: Path) -> bool:
    """Tell whether ``url`` is ``page`` itself, a PNG beside it, or a data: URI."""
    parts = urlsplit(url)
    if parts.scheme == 'data':
        return True
    if parts.scheme != 'file' or parts.netloc not in ('', 'localhost'):
        return False
    path = Path(url2pathname(parts.path))
    return path == page or (path.suffix.lower() == '.png' and page.parent in path.parents)


def problems(browser: 'sync_api.Browser', page_path: Path) -> list[str]:
    """Open the page at ``page_path`` in ``browser``; return what is wrong with it, in words."""
    page_path = page_path.resolve()
    found: list[str] = []
    passed: list[str] = []
    context = browser.new_context(service_workers='block')

    def route(r: 'sync_api.Route') -> None:
        if is_own(r.request.url, page_path):
            passed.append(r.request.url)
            r.continue_()
        else:
            found.append(f'outside request: {short(r.request.url)}')
            r.abort('blockedbyclient')

    def console(msg: 'sync_api.ConsoleMessage') -> None:
        if msg.type == 'error':
            found.append(f'console error: {msg.text}')

    def failed(request: 'sync_api.Request') -> None:
        # The aborted ones are named above; this is a file of its own that did not load.
        if is_own(request.url, page_path):
            found.append(f'request failed: {short(request.url)} ({request.failure})')

    try:
        context.route('**/*', route)
        page = context.new_page()
        page.on('requestfailed', failed)
        page.on('websocket', lambda ws: found.append(f'outside request: {short(ws.url)}'))
        page.on('console', console)
        page.on('pageerror', lambda err: found.append(f'page error: {err}'))
        page.goto(page_path.as_uri(), wait_until='load', timeout=30_000)
        # A request a script or a late load starts after the load event is caught too.
        page.wait_for_load_state('networkidle', timeout=30_000)
        shown = page.evaluate(IMAGES)
    finally:
        context.close()
    if page_path.as_uri() not in passed:
        found.append('the page itself did not pass the route: its requests went unchecked')
    if not shown:
        found.append('no <img> on the page')
    for img in shown:
        if not (img['complete'] and img['width'] > 0 and img['height'] > 0):
            found.append(f'image not loaded: alt={img["alt"]!r} src={short(img["src"])} '
                         f'(complete {img["complete"]}, {img["width"]}x{img["height"]})')
    return found


@pytest.fixture(scope='module')
def browser() -> Iterator['sync_api.Browser']:
    """Start one headless Chromium for every page of the module."""
    with sync_api.sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS, timeout=60_000)
        yield b
        b.close()


@pytest.mark.parametrize('name', ['undershoot', 'hidden', 'no_mv'])
def test_the_page_requests_nothing_outside_and_every_image_loads(
        browser: 'sync_api.Browser', report_pages: dict, name: str) -> None:
    found = problems(browser, report_pages[name][0])
    assert not found, f'{name}:\n' + '\n'.join(found)


def test_the_check_names_an_outside_image_a_broken_one_and_a_script_error(
        browser: 'sync_api.Browser', report_pages: dict, tmp_path: Path) -> None:
    page = report_pages['no_mv'][0].read_text(encoding='utf-8')
    broken = page.replace('</body>', (
        '<img alt="outside" src="https://example.invalid/x.png">'
        '<img alt="cut" src="data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAE">'
        '<script>window.notAFunction();</script></body>'))
    assert broken != page
    (tmp_path / 'broken.html').write_text(broken, encoding='utf-8')
    found = problems(browser, tmp_path / 'broken.html')
    print('\n'.join(found))
    assert 'outside request: https://example.invalid/x.png' in found
    not_loaded = [f for f in found if f.startswith('image not loaded')]
    assert len(not_loaded) == 2  # the page's own figures still load
    assert "alt='outside' src=https://example.invalid/x.png" in not_loaded[0]
    assert "alt='cut' src=data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAE" in not_loaded[1]
    assert any(f.startswith('page error: ') and 'notAFunction' in f for f in found)
