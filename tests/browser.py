"""A page looked at in headless Chromium at a phone's, a tablet's and a desktop's width: does anything run off the
right edge?  Used by the report's and the documentation site's layout tests.

Chromium's headless window is at least 500 px wide, so each width is an iframe of that width on one wrapper page,
and one browser start looks at every width.  A probe script added to (a copy of) the page measures it inside its
frame and posts what it found to the wrapper, which writes it into its own DOM for ``--dump-dom`` to print.
Scrollbars are hidden (``--hide-scrollbars``), as on a phone, so a frame's width is the page's viewport."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

#: a phone (390 px, the common iPhone), a tablet or a narrow desktop window, a laptop
WIDTHS = (390, 800, 1280)
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="no headless Chromium here (apt-get install -y chromium; "
                                                              "Playwright's browser cannot be downloaded offline)")

# An element overflows when its box, or content it lets spill (overflow visible), reaches past the viewport's right
# edge — unless an ancestor clips or scrolls it (a table in its own scroll box is fine; the box itself is measured),
# or it is a fixed drawer parked off the page until it slides in.
# Only the innermost offenders are named (a body too wide because of one table names the table), alike ones once.
_PROBE = """<script>
window.addEventListener('load', () => {
  const root = document.documentElement, view = root.clientWidth;
  document.querySelectorAll('details').forEach(d => { d.open = true; });
  const clipped = el => {
    for (let p = el.parentElement; p && p !== root; p = p.parentElement) {
      if (getComputedStyle(p).overflowX !== 'visible') return true;
    }
    return false;
  };
  const reach = el => {
    const box = el.getBoundingClientRect();
    const spills = getComputedStyle(el).overflowX === 'visible' ? box.left + el.scrollWidth : box.right;
    return box.width ? Math.max(box.right, spills) : 0;
  };
  const offCanvas = el => {  // a drawer parked beyond the right edge until it slides in (furo's contents)
    for (let p = el; p && p !== root; p = p.parentElement) {
      if (getComputedStyle(p).position === 'fixed' && p.getBoundingClientRect().left >= view) return true;
    }
    return false;
  };
  const wide = [...document.body.querySelectorAll('*')]
    .filter(el => reach(el) > view + 0.5 && !clipped(el) && !offCanvas(el));
  const named = el => el.tagName.toLowerCase() + (el.id ? '#' + el.id : '')
    + [...el.classList].map(c => '.' + c).join('');
  const alike = new Map();  // forty ids in one column are one finding
  for (const el of wide.filter(el => !wide.some(o => o !== el && el.contains(o)))) {
    const [n, most] = alike.get(named(el)) || [0, 0];
    alike.set(named(el), [n + 1, Math.max(most, Math.ceil(reach(el)))]);
  }
  const offenders = [...alike].map(([name, [n, most]]) => `${name}${n > 1 ? ' ×' + n : ''} reaches ${most} px`);
  const extra = (() => { /*EXTRA*/ })() || {};
  parent.postMessage(JSON.stringify({frame: location.hash.slice(1), view, scroll: root.scrollWidth, offenders,
                                     extra}), '*');
});
</script></body>"""

_WRAPPER = """<!DOCTYPE html><html><head><meta charset="utf-8"></head><body style="margin:0">
<script>
window.addEventListener('message', event => {
  const out = document.createElement('script');
  out.type = 'application/json'; out.className = 'hil-layout'; out.textContent = event.data;
  document.body.appendChild(out);
});
</script>
FRAMES
</body></html>"""


@dataclass(frozen=True)
class Layout:
    """One page at one width, as the probe measured it."""

    width: int
    view: int  # the page's viewport width (the frame's, without a scrollbar)
    scroll_width: int  # the document's: wider than ``view`` when the page scrolls sideways
    offenders: list[str]  # the innermost elements reaching past the right edge, e.g. "code ×40 reaches 452 px"
    extra: dict[str, Any] = field(default_factory=dict)  # what the caller's ``extra_js`` returned

    @property
    def fits(self) -> bool:
        return self.scroll_width <= self.view and not self.offenders


def look(page: Path, widths: tuple[int, ...] = WIDTHS, extra_js: str = "") -> dict[int, Layout]:
    """``page`` at each width (one Chromium start); ``extra_js``: a function body run in the page after the
    measurement (every ``<details>`` open) whose returned object comes back as :attr:`Layout.extra`.

    The probed copy and the wrapper are written beside ``page``, so its relative links (CSS, scripts) resolve."""
    assert CHROMIUM, "look() needs Chromium: mark the test with needs_chromium"
    probed = page.with_name(f"_probed_{page.name}")
    text = page.read_text(encoding="utf-8")
    probed.write_text(text.replace("</body>", _PROBE.replace("/*EXTRA*/", extra_js), 1), encoding="utf-8")
    frames = "\n".join(f'<iframe src="{probed.name}#{w}" width="{w}" height="900" style="border:0;display:block">'
                       f"</iframe>" for w in widths)
    wrapper = page.with_name(f"_frames_{page.name}")
    wrapper.write_text(_WRAPPER.replace("FRAMES", frames), encoding="utf-8")
    done = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                           f"--window-size={max(widths) + 20},{900 * len(widths)}", "--virtual-time-budget=5000",
                           "--dump-dom", wrapper.as_uri()], capture_output=True, text=True, timeout=120)
    found = [json.loads(m) for m in re.findall(r'<script type="application/json" class="hil-layout">(.*?)</script>',
                                                done.stdout, re.S)]
    layouts = {int(f["frame"]): Layout(int(f["frame"]), f["view"], f["scroll"], f["offenders"], f["extra"])
               for f in found}
    assert set(layouts) == set(widths), (f"the probe reported {sorted(layouts)} of {widths}:\n"
                                         f"{done.stdout[-800:]}\n{done.stderr[-800:]}")
    return layouts
