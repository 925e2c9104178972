"""Headless Chromium for the report tests: a page's layout facts measured in the browser.

Chromium's own headless mode (no driver library): the test copies the page, adds a script
that measures the laid-out page once it has loaded and writes the facts as JSON into the
DOM, and reads them back from `--dump-dom`.  Needs a chromium binary (Debian package
'chromium'; .ci/run installs it); the tests skip with that reason where there is none.
"""

from __future__ import annotations

import html
import json
import re
import shutil
import subprocess
from pathlib import Path

CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")
                 if shutil.which(n)), None)
NO_BROWSER = ("no chromium binary found (install the Debian package 'chromium'; .ci/run "
              "does): the reports' layout in a real browser is not checked here")
MIN_WINDOW = 500  # headless Chromium's narrowest window (px); narrower pages are boxed
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--hide-scrollbars", "--force-device-scale-factor=1"]

MEASURE = r"""
<script>
window.addEventListener('load', function () {
  function lum(c) {
    var m = c.match(/[\d.]+/g).map(Number);
    var a = m.length > 3 ? m[3] : 1;
    return {rgb: m.slice(0, 3).map(function (v) {
      v /= 255; return v <= 0.03928 ? v / 12.92 : Math.pow((v + 0.055) / 1.055, 2.4); }),
      a: a};
  }
  function L(c) { var x = lum(c).rgb; return 0.2126 * x[0] + 0.7152 * x[1] + 0.0722 * x[2]; }
  function background(el) {
    while (el) {
      var b = getComputedStyle(el).backgroundColor;
      if (lum(b).a > 0) return b;
      el = el.parentElement;
    }
    return 'rgb(255, 255, 255)';
  }
  function contrast(el) {
    var f = L(getComputedStyle(el).color), b = L(background(el));
    return (Math.max(f, b) + 0.05) / (Math.min(f, b) + 0.05);
  }
  var W = window.PAGE_WIDTH || document.documentElement.clientWidth, wide = [],
      small = [], minFont = 99, scrolled = [], maxRight = 0;
  function inScroller(el) {  // inside a box that scrolls sideways (a wide table's .wrap)
    for (var a = el.parentElement; a && a !== document.body; a = a.parentElement) {
      var o = getComputedStyle(a).overflowX;
      if ((o === 'auto' || o === 'scroll') && a.getBoundingClientRect().right <= W + 1)
        return true;
    }
    return false;
  }
  var all = document.body.getElementsByTagName('*');
  for (var i = 0; i < all.length; i++) {
    var el = all[i], r = el.getBoundingClientRect();
    if (r.width === 0 && r.height === 0) continue;
    if (el.closest('details:not([open])') && el.tagName !== 'SUMMARY') continue;
    if (r.right > W + 1 || r.left < -1) {
      var what = el.tagName + '#' + el.id + '.' + el.className + ' ' + Math.round(r.left) +
        '..' + Math.round(r.right);
      if (inScroller(el)) scrolled.push(what); else wide.push(what);
    }
    if (!inScroller(el) && r.right > maxRight) maxRight = r.right;
    var own = Array.prototype.some.call(el.childNodes, function (n) {
      return n.nodeType === 3 && n.textContent.trim(); });
    if (own) {
      var fs = parseFloat(getComputedStyle(el).fontSize);
      if (fs < minFont) minFont = fs;
      if (fs < 9) small.push(el.tagName + ' ' + fs + 'px: ' + el.textContent.slice(0, 40));
    }
  }
  var banners = [].map.call(document.querySelectorAll('.banner'), function (b) {
    return {text: b.textContent.slice(0, 80), contrast: contrast(b)}; });
  var rows = [].map.call(document.querySelectorAll('#check tr[data-status]'), function (t) {
    var a = t.querySelector('a');
    return {status: t.getAttribute('data-status'), contrast: contrast(t.querySelector('td')),
            link: a ? a.getAttribute('href') : null}; });
  var verdictText = [].map.call(document.querySelectorAll('#check-table td:last-child'),
    function (td) { return Math.round(td.getBoundingClientRect().width); });
  var figureWidths = [].map.call(document.querySelectorAll('figure img'), function (im) {
    return Math.round(im.getBoundingClientRect().width); });
  var imgs = [].filter.call(document.images, function (im) {
    return !(im.complete && im.naturalWidth > 0); }).map(function (im) { return im.alt; });
  // what a person sees: the rendered text, searched for markup shown as text
  var seen = document.body.innerText, markup = [];
  ['<table', '<div', '<td', '<tr', '<p ', '<p>', '</', '&lt;', '&gt;', '&amp;', '&quot;'
  ].forEach(function (m) {
    var i = seen.indexOf(m);
    if (i >= 0) markup.push(m + ' in "' + seen.slice(Math.max(0, i - 40), i + 60) + '"');
  });
  var facts = {height: document.documentElement.scrollHeight, width: W,
    scrolled: scrolled.slice(0, 20), n_scrolled: scrolled.length,
    visible_markup: markup, text_length: seen.length,
    text_sample: seen.slice(0, 4000),
    tables: [].map.call(document.querySelectorAll('table'), function (t) { return t.id; }),
    scroll_width: window.PAGE_WIDTH ? Math.round(Math.max(W, maxRight))
      : document.documentElement.scrollWidth,
    wide: wide.slice(0, 20),
    small: small.slice(0, 20), min_font: minFont, banners: banners, check_rows: rows,
    verdict_text_widths: verdictText, figure_widths: figureWidths,
    sections: [].map.call(document.querySelectorAll('section[id]'), function (s) {
      return s.id; }),
    section_heights: [].map.call(document.querySelectorAll('section[id]'), function (s) {
      return [s.id, Math.round(s.getBoundingClientRect().height)]; }),
    broken_images: imgs, n_images: document.images.length};
  var out = document.createElement('pre');
  out.id = 'layout-facts';
  out.textContent = JSON.stringify(facts);
  document.body.appendChild(out);
});
</script>
"""


def run(args: list[str], profile: Path, timeout: float = 180) -> subprocess.CompletedProcess:
    return subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={profile}", *args],
                          capture_output=True, text=True, timeout=timeout)


def layout_facts(page: Path, width: int, work: Path) -> dict:
    """The facts of `page` laid out `width` px wide: height, elements beyond the page,
    text below 9 px (`wide`; `scrolled`: beyond it inside a box that scrolls sideways, a wide
    table's own scroll bar), banner and verdict-row contrast, sections, images that failed, markup
    visible as text (`visible_markup`, from `document.body.innerText`: what a person
    reads), the ids of the table elements."""
    work.mkdir(parents=True, exist_ok=True)
    probe = work / f"probe-{page.stem}.html"
    text = page.read_text(encoding="utf-8")
    narrow = ""
    if width < MIN_WINDOW:  # a phone: the page laid out in a box of its width
        narrow = (f"<style>html{{width:{width}px;overflow-x:hidden}}</style>"
                  f"<script>window.PAGE_WIDTH = {width};</script>")
    probe.write_text(text.replace("</body>", narrow + MEASURE + "</body>"), encoding="utf-8")
    r = run([f"--window-size={max(width, MIN_WINDOW)},1000", "--virtual-time-budget=20000",
             "--dump-dom", probe.as_uri()], work / "profile")
    m = re.search(r'<pre id="layout-facts">([^<]*)</pre>', r.stdout)
    if not m:
        raise AssertionError(f"the measuring script did not run (rc {r.returncode}): "
                             + r.stderr[-1500:])
    return json.loads(html.unescape(m.group(1)))


def screenshot(page: Path, png: Path, work: Path, width: int = 1400,
               height: int = 2000) -> bytes:
    """The page captured as a person's screen shows it (`width` x `height` px)."""
    png.unlink(missing_ok=True)
    r = run([f"--window-size={width},{height}", f"--screenshot={png}", page.as_uri()],
            work / "profile-shot")
    assert r.returncode == 0 and png.is_file(), r.stderr[-1500:]
    return png.read_bytes()


def print_pdf(page: Path, pdf: Path, work: Path) -> None:
    """The page printed to PDF by Chromium (what a reader's browser prints)."""
    r = run(["--no-pdf-header-footer", f"--print-to-pdf={pdf}", page.as_uri()],
            work / "profile-print")
    assert r.returncode == 0 and pdf.is_file(), r.stderr[-1500:]
