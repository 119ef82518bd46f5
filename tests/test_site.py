"""The course site (``python -m sphinx -b html docs build/site``) built and read in a real browser.

One build per test session (into a temporary folder, warnings as errors, without the course log),
then headless Chromium through selenium, started as in ``tests/test_browser_demos.py`` and with no
network, opens every page from ``file://`` and checks what a reader would meet: one page per lesson
notebook in the order of their numbers and none for the solutions; every page loads with no console
error; every internal link resolves to an existing file and, with a ``#fragment``, to an element with
that id; MathJax (served from the site itself) has typeset every formula and no raw ``$``, ``\\(``
or ``\\begin{`` is left in the text; every image is loaded (the demos' stored images included); the search page finds
a word; and the browser requested nothing but ``file:``/``data:``/``blob:`` URLs.

Needs Sphinx and myst-nb (pinned in ``environment.txt``); the tests that open a browser also need
Chromium with chromedriver (Debian: ``apt-get install chromium chromium-driver``). Each is skipped,
with the reason, without them.
``KFCAL_CHROMIUM`` / ``KFCAL_CHROMEDRIVER`` select other binaries.
"""

from __future__ import annotations

import html.parser
import json
import os
import re
import subprocess
import sys
import time
import urllib.parse
from pathlib import Path

import pytest
from chromium import CHROMEDRIVER, CHROMIUM, start

ROOT = Path(__file__).resolve().parents[1]
LESSONS = sorted(p.stem for p in (ROOT / "notebooks").glob("[0-9][0-9]*_*.ipynb"))
LOCAL_SCHEMES = {"file", "data", "blob", "about"}
NETWORK_SCHEMES = {"http", "https", "ws", "wss", "ftp"}
WINDOW = (1280, 900)



pytest.importorskip("sphinx", reason="site test skipped: Sphinx is not installed (pip install -r environment.txt)")
pytest.importorskip("myst_nb", reason="site test skipped: myst-nb is not installed (pip install -r environment.txt)")
needs_browser = pytest.mark.skipif(
    CHROMIUM is None or CHROMEDRIVER is None,
    reason=("browser test of the course site skipped: no Chromium/chromedriver found "
            f"(chromium: {CHROMIUM or 'missing'}, chromedriver: {CHROMEDRIVER or 'missing'}; "
            "Debian: apt-get install chromium chromium-driver)"))


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """The site built once, as the documented command builds it, plus ``-W`` (a warning fails)."""
    out = tmp_path_factory.mktemp("site") / "html"
    env = {k: v for k, v in os.environ.items() if k != "KFCAL_COURSE_LOG"}  # the log is not needed
    start = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "sphinx", "-b", "html", "-W", "--keep-going", "-q",
                          "docs", str(out)], cwd=ROOT, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    assert run.returncode == 0, f"site build failed:\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}"
    print(f"site built in {seconds:.1f} s", file=sys.stderr)
    return out


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    # console messages, and the network events (every URL the page requests)
    driver = start(WINDOW, tmp_path_factory.mktemp('chromium-profile'), {"browser": "ALL", "performance": "ALL"})
    try:
        driver.set_window_size(*WINDOW)
        driver.set_script_timeout(60)
        yield driver
    finally:
        driver.quit()


class _Page(html.parser.HTMLParser):
    """The ids (and names) a page defines and the hrefs/srcs it links to."""

    def __init__(self):
        super().__init__()
        self.ids: set[str] = set()
        self.links: list[str] = []  # every href/src
        self.loads: list[str] = []  # what the browser loads by itself: img/script src, <link> href

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        for key in ("id", "name"):
            if attrs.get(key):
                self.ids.add(attrs[key])
        if tag == "a" and attrs.get("href"):
            self.links.append(attrs["href"])
        if tag in ("img", "script", "iframe", "source", "video", "audio") and attrs.get("src"):
            self.links.append(attrs["src"])
            self.loads.append(attrs["src"])
        if tag == "link" and attrs.get("href"):
            self.links.append(attrs["href"])
            self.loads.append(attrs["href"])


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    return page


def _pages(site: Path) -> list[Path]:
    return sorted(p for p in site.rglob("*.html") if "_static" not in p.relative_to(site).parts)


# MathJax: wait for the typesetting of the page, then report what is left
_MATH_JS = """
const done = arguments[arguments.length - 1];
const finish = () => {
    const math = Array.from(document.querySelectorAll('.math'));
    const untypeset = math.filter(e => !e.querySelector('mjx-container')).map(e => e.textContent.slice(0, 80));
    const errors = Array.from(document.querySelectorAll('mjx-merror, [data-mjx-error]'))
        .map(e => (e.getAttribute('data-mjx-error') || e.textContent).slice(0, 80));
    // text a reader sees, outside code, outputs and typeset math: no raw $ or \\( left
    const walker = document.createTreeWalker(document.body, NodeFilter.SHOW_TEXT);
    const raw = [];
    for (let n = walker.nextNode(); n; n = walker.nextNode()) {
        const p = n.parentElement;
        if (p.closest('pre, code, script, style, mjx-container, .highlight, .cell_output, textarea')) continue;
        const t = n.textContent;
        if (/[$]|\\\\[(\\[]|\\\\begin[{]/.test(t) && p.offsetParent !== null) raw.push(t.trim().slice(0, 80));
    }
    done({n_math: math.length, n_typeset: document.querySelectorAll('mjx-container').length,
          untypeset, errors, raw});
};
if (!document.querySelector('.math')) { finish(); }
else {
    const wait = () => (window.MathJax && MathJax.startup && MathJax.startup.promise)
        ? MathJax.startup.promise.then(finish, e => done({failed: String(e)})) : setTimeout(wait, 50);
    wait();
}
"""

_IMAGES_JS = """
return Array.from(document.images).map(i => ({src: i.getAttribute('src'), ok: i.complete && i.naturalWidth > 0}));
"""


def _outside_requests(driver) -> list[str]:
    """URLs requested since the last call that leave the site: any network URL, and anything but
    ``file:``/``data:``/``blob:`` asked for by a page of the site (the browser's own start page
    loads ``chrome://`` resources of its own, which are not the site's)."""
    urls = []
    for entry in driver.get_log("performance"):
        message = json.loads(entry["message"])["message"]
        if message.get("method") == "Network.requestWillBeSent":
            url = message["params"]["request"]["url"]
            scheme = urllib.parse.urlsplit(url).scheme
            from_site = urllib.parse.urlsplit(message["params"].get("documentURL", "")).scheme == "file"
            if scheme in NETWORK_SCHEMES or (from_site and scheme not in LOCAL_SCHEMES):
                urls.append(url)
    return urls


def _open(driver, url: str, timeout: float = 60.0) -> None:
    """Open ``url`` and wait until its document has loaded (``readyState`` "complete").

    WebDriver's ``get`` alone is not enough: on a busy machine headless Chromium has been seen to
    return from it with the new page still "loading" (1.8 kB of a 260 kB lesson parsed), so that
    what comes later in the page (a demo's note, its images) was not there yet."""
    from selenium.webdriver.support.ui import WebDriverWait

    driver.get(url)
    WebDriverWait(driver, timeout, poll_frequency=0.02).until(
        lambda d: d.execute_script("return document.readyState === 'complete' && location.href;") == url,
        f"{url} did not finish loading in {timeout:.0f} s")


def _console(driver) -> list[str]:
    return [f"{e['level']}: {e['message'][:300]}" for e in driver.get_log("browser")
            if e["level"] in ("SEVERE", "WARNING")]


def test_one_page_per_lesson_in_order_and_no_solutions(site):
    pages = {p.relative_to(site).as_posix() for p in _pages(site)}
    assert {f"lessons/{name}.html" for name in LESSONS} <= pages, sorted(pages)
    assert not [p for p in pages if "solution" in p.lower()], "a solutions page is on the site"
    assert not list(site.rglob("*solutions*")), "solutions files were copied into the site"
    # the start page's table of contents lists the lessons in the order of their numbers
    index = _parse(site / "index.html")
    order = [link.split("#")[0].removeprefix("lessons/").removesuffix(".html") for link in index.links
             if link.startswith("lessons/")]
    toc = list(dict.fromkeys(order))
    assert toc == LESSONS, toc
    # every lesson page links its predecessor and successor (prev/next navigation)
    for before, after in zip(LESSONS, LESSONS[1:]):
        text = (site / "lessons" / f"{before}.html").read_text(encoding="utf-8")
        assert re.search(f'<link rel="next" title="[^"]*" href="{after}.html"', text), (before, after)
        after_text = (site / "lessons" / f"{after}.html").read_text(encoding="utf-8")
        assert re.search(f'<link rel="prev" title="[^"]*" href="{before}.html"', after_text), (after, before)


def test_internal_links_resolve_and_nothing_loads_from_outside(site):
    ids = {}
    broken, remote = [], set()
    for page in _pages(site):
        parsed = _parse(page)
        remote |= {f"{page.relative_to(site)}: {link}" for link in parsed.loads
                   if link.startswith("//") or urllib.parse.urlsplit(link).scheme in ("http", "https")}
        for link in parsed.links:
            parts = urllib.parse.urlsplit(link)
            if parts.scheme in ("http", "https", "mailto") or link.startswith("//"):
                continue  # a link to another site (only followed when clicked)
            if parts.scheme in ("data", "javascript"):
                continue
            target = (page.parent / urllib.parse.unquote(parts.path)).resolve() if parts.path else page
            if not target.is_file():
                broken.append(f"{page.relative_to(site)} -> {link} (no file)")
                continue
            if parts.fragment and target.suffix == ".html":
                if target not in ids:
                    ids[target] = _parse(target).ids
                if urllib.parse.unquote(parts.fragment) not in ids[target]:
                    broken.append(f"{page.relative_to(site)} -> {link} (no such anchor)")
    assert not broken, "\n".join(broken[:30])
    # the site is read offline: no image, script, stylesheet or font is loaded from another site
    assert not remote, sorted(remote)


def test_no_stylesheet_or_script_loads_from_the_network(site):
    """No CSS of the site imports a stylesheet or a font from the network, and no page loads MathJax
    or a theme file from a CDN (the browser test also watches the requests; this one needs no browser)."""
    remote = re.compile(r"""(@import\s+(url\()?\s*['"]?|url\(\s*['"]?)(https?:)?//""")
    found = [f"{css.relative_to(site)}: {m.group(0)}" for css in site.rglob("*.css")
             for m in remote.finditer(css.read_text(encoding="utf-8", errors="replace"))]
    assert not found, found
    mathjax = site / "_static" / "mathjax" / "tex-chtml.js"
    assert mathjax.is_file() and mathjax.stat().st_size > 500_000, "MathJax is not inside the built site"
    for page in _pages(site):
        scripts = [link for link in _parse(page).links if "mathjax" in link.lower()]
        assert scripts and all(not urllib.parse.urlsplit(link).scheme for link in scripts), (page, scripts)


@needs_browser
def test_every_page_in_the_browser(site, browser):
    """Each page loads from file://, typesets all its math, shows all its images, logs no console
    error or warning and requests no URL outside the site."""
    problems = []
    n_math = n_images = n_pages = 0
    browser.get_log("performance")
    browser.get_log("browser")
    for page in _pages(site):
        name = page.relative_to(site).as_posix()
        _open(browser, page.as_uri())
        math = browser.execute_async_script(_MATH_JS)
        if "failed" in math:
            problems.append(f"{name}: MathJax failed: {math['failed']}")
        else:
            n_math += math["n_math"]
            if math["untypeset"]:
                problems.append(f"{name}: math not typeset: {math['untypeset'][:3]}")
            if math["errors"]:
                problems.append(f"{name}: MathJax errors: {math['errors'][:3]}")
            if math["raw"]:
                problems.append(f"{name}: raw TeX delimiters in the text: {math['raw'][:3]}")
        images = browser.execute_script(_IMAGES_JS)
        n_images += len(images)
        problems += [f"{name}: image not loaded: {i['src']}" for i in images if not i["ok"]]
        problems += [f"{name}: console {m}" for m in _console(browser)]
        n_pages += 1
        problems += [f"{name}: request to {u[:120]}" for u in _outside_requests(browser)]
    assert not problems, "\n".join(problems[:40])
    assert n_pages >= len(LESSONS) + 3  # the lessons, the start page, the index, the search page
    assert n_math > 500, f"only {n_math} formulas on the whole site"
    assert n_images >= len(LESSONS), f"only {n_images} images on the whole site"


@needs_browser
@pytest.mark.parametrize("name", [n for n in LESSONS if "live_demo" in n])
def test_demo_pages_show_the_stored_image(site, browser, name):
    """The live demo's widget becomes the image it stored and the note that its controls need Jupyter."""
    from selenium.webdriver.common.by import By

    _open(browser, (site / "lessons" / f"{name}.html").as_uri())
    note = browser.find_elements(By.CSS_SELECTOR, ".kfcal-live-note")
    assert len(note) == 1, f"{len(note)} live-demo notes on {name}"
    # the cell holding the note holds the demo's stored image, loaded
    cell = note[0].find_element(By.XPATH, "ancestor::div[contains(@class, 'cell_output')]")
    images = cell.find_elements(By.TAG_NAME, "img")
    assert len(images) == 1, f"{len(images)} images in the demo's cell of {name}"
    size = browser.execute_script("const i = arguments[0]; return [i.complete, i.naturalWidth, i.naturalHeight];",
                                  images[0])
    assert size[0] and size[1] >= 300 and size[2] >= 200, size
    assert "application/vnd.jupyter.widget" not in browser.page_source


@needs_browser
def test_search_finds_a_word(site, browser):
    """Sphinx's search works from file:// with no server: 'filterpy' is found on several lessons."""
    from selenium.webdriver.common.by import By

    browser.get_log("browser")
    _open(browser, (site / "search.html").as_uri() + "?q=filterpy")
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        hits = browser.find_elements(By.CSS_SELECTOR, "#search-results ul.search li a")
        status = browser.find_elements(By.CSS_SELECTOR, "#search-results .search-summary")
        if status and status[0].text.strip() and hits:
            break
        time.sleep(0.2)
    found = {h.get_attribute("href").split("/")[-1].split(".html")[0] for h in hits}
    assert len(found & set(LESSONS)) >= 3, f"search for 'filterpy' found {sorted(found)}"
    assert not [m for m in _console(browser) if m.startswith("SEVERE")]


def test_mathjax_license_travels_with_the_site(site):
    """MathJax (Apache License 2.0) is redistributed inside the site, so its license goes with it,
    linked from the start page."""
    license_file = site / "_static" / "mathjax" / "LICENSE"
    assert license_file.is_file(), "MathJax's license is not in the built site"
    text = license_file.read_text(encoding="utf-8")
    assert "MathJax" in text and "Apache License" in text and "Version 2.0, January 2004" in text
    assert "END OF TERMS AND CONDITIONS" in text  # the whole license, not a pointer to it
    assert "_static/mathjax/LICENSE" in _parse(site / "index.html").links


class _OutputImages(html.parser.HTMLParser):
    """Each <img> inside a notebook cell's output (``div.cell_output``): its src, its style and
    the href of the link around it (None without one)."""

    def __init__(self):
        super().__init__()
        self.divs: list[bool] = []  # for each open div: is it a cell output?
        self.link: list[str | None] = []
        self.images: list[tuple[str, str, str | None]] = []

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "div":
            self.divs.append("cell_output" in (attrs.get("class") or "").split())
        elif tag == "a":
            self.link.append(attrs.get("href"))
        elif tag == "img" and any(self.divs):
            self.images.append((attrs["src"], attrs.get("style") or "", self.link[-1] if self.link else None))

    def handle_endtag(self, tag):
        if tag == "div" and self.divs:
            self.divs.pop()
        elif tag == "a" and self.link:
            self.link.pop()


def test_output_figures_open_full_size(site):
    """The page's column (688 px in a 1280 px window) shrinks a figure wider than it; every figure a
    cell printed is shown at most at its own pixel width and links to its file, which a click opens at
    full size."""
    import struct

    checked, problems = 0, []
    for page in _pages(site):
        parser = _OutputImages()
        parser.feed(page.read_text(encoding="utf-8"))
        for src, style, href in parser.images:
            name = f"{page.relative_to(site)}: {src}"
            if href != src:
                problems.append(f"{name} links to {href!r}, not to its file")
                continue
            data = (page.parent / urllib.parse.unquote(src)).read_bytes()
            if data[:8] == b"\x89PNG\r\n\x1a\n":
                width = struct.unpack(">I", data[16:20])[0]
                if f"width: {width}px" not in style:
                    problems.append(f"{name} is {width} px wide, its style says {style!r}")
            checked += 1
    assert not problems, "\n".join(problems[:20])
    assert checked >= len(LESSONS), f"only {checked} output figures found"


def _heading(path: Path, pattern: str) -> str | None:
    """The first markdown line of ``path`` (a MyST source) after its front matter that matches ``pattern``,
    without it (a YAML comment in the front matter is no heading)."""
    lines = path.read_text(encoding="utf-8").splitlines()
    if lines and lines[0] == "---":
        lines = lines[lines.index("---", 1) + 1:]
    for line in lines:
        match = re.fullmatch(pattern, line)
        if match:
            return match.group(1)
    return None


def _readme_titles() -> dict[str, str]:
    """{notebook stem: title} from README's notebook table, whose rows start ``| [NN · Title](notebooks/stem.ipynb) |``."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    return {m.group(2): m.group(1) for m in re.finditer(r"^\| \[([^\]]+)\]\(notebooks/([^)/]+)\.ipynb\) \|", text, re.M)}


def _text(html_fragment: str) -> str:
    """The text of an HTML fragment (tags dropped, entities and typographic quotes made plain)."""
    import html as html_module

    text = html_module.unescape(re.sub(r"<[^>]+>", "", html_fragment))
    return re.sub(r"\s+", " ", text.replace("’", "'").replace("‘", "'")).strip()


def test_lesson_titles_agree_in_notebooks_readme_and_site(site):
    """One title style, "NN · Title", for every lesson: the first heading of its source and of its
    rendered notebook, its solutions' heading ("Solutions · NN · Title"), README's notebook table and
    the site's page (its title and first heading).  README's title is the heading up to its subtitle
    (after a colon or a comma), the solutions' heading's title."""
    import json

    readme = _readme_titles()
    assert sorted(readme) == LESSONS, f"README's table lists {sorted(readme)}"
    problems = []
    for stem in LESSONS:
        number = stem.split("_")[0]
        source = ROOT / "notebooks" / "source" / f"{stem}.md"
        heading = _heading(source, r"# (.+)")
        title = readme[stem]
        if not heading.startswith(f"{number} · "):
            problems.append(f"{stem}: heading {heading!r} does not start with {number + ' · '!r}")
        if not (heading == title or heading.startswith(title + ":") or heading.startswith(title + ",")):
            problems.append(f"{stem}: README's title {title!r} is not the heading {heading!r} or its start")
        solutions = _heading(source, r"# (Solutions .+)")
        if solutions is not None and solutions != f"Solutions · {title}":
            problems.append(f"{stem}: solutions heading {solutions!r}, README {title!r}")
        for path in (ROOT / "notebooks" / f"{stem}.ipynb", ROOT / "notebooks" / "solutions" / f"{stem}.ipynb"):
            if not path.exists():
                continue
            cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
            first = "".join(cells[0]["source"]).splitlines()[0]
            expected = f"# {heading}" if path.parent.name == "notebooks" else f"# {solutions}"
            if first != expected:
                problems.append(f"{path.relative_to(ROOT)}: first line {first!r}, expected {expected!r}")
        page = (site / "lessons" / f"{stem}.html").read_text(encoding="utf-8")
        page_title = _text(re.search(r"<title>(.*?)</title>", page, re.S).group(1))
        h1 = _text(re.search(r"<h1[^>]*>(.*?)</h1>", page, re.S).group(1)).removesuffix("#").strip()
        plain = re.sub(r"\$([^$]*)\$", r"\\(\1\\)", heading).replace("’", "'")
        if not page_title.startswith(plain + " — "):
            problems.append(f"{stem}: the site's page title {page_title!r}, the heading {plain!r}")
        if not h1.startswith(title.split("$")[0]):
            problems.append(f"{stem}: the site's first heading {h1!r}, README {title!r}")
    assert not problems, "\n".join(problems)


def test_readme_and_site_credit_the_courses_and_filterpy(site):
    """README and the site's start page name the courses whose problems, numbers and notation the
    lessons use, and filterpy's author."""
    readme = re.sub(r"\s+", " ", (ROOT / "README.md").read_text(encoding="utf-8"))
    start = _text((site / "index.html").read_text(encoding="utf-8"))
    for text, where in ((readme, "README"), (start, "the site's start page")):
        for name in ("ASEN 5044", "Statistical Estimation for Dynamical Systems", "University of Colorado Boulder",
                     "MAE 271A", "University of California, Los Angeles", "filterpy", "Roger R. Labbe Jr.",
                     "MathJax"):
            assert name in text, f"{where} does not name {name!r}"


_OUTPUT_IMAGES_JS = """
return Array.from(document.querySelectorAll('div.cell_output img')).map(i => {
    const r = i.getBoundingClientRect(), s = getComputedStyle(i);
    const px = (...names) => names.reduce((sum, n) => sum + parseFloat(s[n] || 0), 0);
    const a = i.closest('a');
    // the content box: the dark theme pads images
    const shown = [r.width - px('paddingLeft', 'paddingRight', 'borderLeftWidth', 'borderRightWidth'),
                   r.height - px('paddingTop', 'paddingBottom', 'borderTopWidth', 'borderBottomWidth')];
    return {src: i.getAttribute('src'), natural: [i.naturalWidth, i.naturalHeight], shown: shown,
            href: a ? a.getAttribute('href') : null};
});
"""


@needs_browser
def test_output_figures_in_the_browser(site, browser):
    """In a 1280 px window each figure a cell printed is shown no wider than its own pixels, with its
    shape kept, and the link around it opens its file."""
    problems, n = [], 0
    for name in LESSONS:
        _open(browser, (site / "lessons" / f"{name}.html").as_uri())
        for image in browser.execute_script(_OUTPUT_IMAGES_JS):
            (nw, nh), (w, h) = image["natural"], image["shown"]
            n += 1
            if not (nw and w):
                problems.append(f"{name}: {image['src']} not shown")
            elif w > nw + 0.5 or abs(h / w - nh / nw) > 0.02:
                problems.append(f"{name}: {image['src']} is {nw} x {nh} px, shown {w:.0f} x {h:.0f}")
            elif image["href"] != image["src"]:
                problems.append(f"{name}: {image['src']} links to {image['href']!r}")
    assert not problems, "\n".join(problems[:20])
    assert n >= len(LESSONS)
