"""The HMI's templates, stylesheet and scripts in a real browser, without the application server.

A tiny HTTP server serves ``static/`` and pages rendered here from ``templates/`` with Jinja2
(StrictUndefined: a template must not need more context than base.html documents). It also
stands in for the few endpoints the scripts talk to: ``/events`` (server-sent events),
``/check`` (a model check returning the error list) and ``/echo`` (shows the CSRF header).

Playwright drives Debian's Chromium (/usr/bin/chromium); screenshots go to tests/screenshots/.
"""

from __future__ import annotations

import http.server
import json
import queue
import threading
from collections.abc import Callable, Iterator
from types import SimpleNamespace
from typing import Any

import pytest
from jinja2 import Environment, FileSystemLoader, StrictUndefined, select_autoescape

from tests.support.paths import REPOSITORY, SCREENSHOTS

ROOT = REPOSITORY
TEMPLATES = ROOT / "templates"
SCREENSHOTS = SCREENSHOTS
DEMO_MODEL = ROOT / "models" / "demo_station.yaml"
CSRF = "test-csrf-token"
WATCH = {"width": 320, "height": 320}
DESKTOP = {"width": 1280, "height": 800}


# ---- fixtures: browser, site, page ----------------------------------------------------------


class _Site(http.server.ThreadingHTTPServer):
    daemon_threads = True

    def __init__(self) -> None:
        super().__init__(("127.0.0.1", 0), _Handler)
        self.pages: dict[str, str] = {}
        self.csrf_headers: list[str | None] = []
        self.check_fragment = ""
        self.sse_streams: list[queue.Queue[bytes | None]] = []
        self.sse_refused = False
        self.lock = threading.Lock()

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.server_address[1]}"

    def push_event(self, name: str, data: str) -> None:
        with self.lock:
            for stream in self.sse_streams:
                stream.put(f"event: {name}\ndata: {data}\n\n".encode())

    def drop_events(self, refuse: bool = True) -> None:
        """Close every open event stream; with refuse, answer reconnects with 503."""
        with self.lock:
            self.sse_refused = refuse
            for stream in self.sse_streams:
                stream.put(None)
            self.sse_streams.clear()


class _Handler(http.server.SimpleHTTPRequestHandler):
    server: _Site

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, directory=str(ROOT), **kwargs)

    def log_message(self, format: str, *args: Any) -> None:
        pass

    def _send(self, body: str, status: int = 200, content_type: str = "text/html") -> None:
        data = body.encode()
        self.send_response(status)
        self.send_header("Content-Type", f"{content_type}; charset=utf-8")
        self.send_header("Content-Length", str(len(data)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(data)

    def do_GET(self) -> None:
        path = self.path.split("?", 1)[0]
        if path in self.server.pages:
            self._send(self.server.pages[path])
        elif path == "/events":
            self._events()
        elif path.startswith("/static/") and ".." not in path:
            super().do_GET()
        else:
            self._send("not found", 404, "text/plain")

    def do_POST(self) -> None:
        length = int(self.headers.get("Content-Length") or 0)
        self.rfile.read(length)
        token = self.headers.get("X-CSRF-Token")
        self.server.csrf_headers.append(token)
        if self.path == "/check":
            self._send(self.server.check_fragment)
        elif self.path == "/echo":
            self._send(f'<p id="echo-result">token {token}</p>')
        else:
            self._send("not found", 404, "text/plain")

    def _events(self) -> None:
        with self.server.lock:
            if self.server.sse_refused:
                self._send("unavailable", 503, "text/plain")
                return
            stream: queue.Queue[bytes | None] = queue.Queue()
            self.server.sse_streams.append(stream)
        self.send_response(200)
        self.send_header("Content-Type", "text/event-stream")
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        try:
            self.wfile.write(b": connected\n\n")
            self.wfile.flush()
            while (item := stream.get(timeout=60)) is not None:
                self.wfile.write(item)
                self.wfile.flush()
        except (queue.Empty, OSError):
            pass


_ENV = Environment(
    loader=FileSystemLoader(TEMPLATES),
    autoescape=select_autoescape(["html"], default_for_string=True),
    undefined=StrictUndefined,
)


def render(template: str, **context: Any) -> str:
    """Render a template file (name ends with .html) or template source, with base context."""
    base: dict[str, Any] = {
        "request": None,
        "user": None,
        "csrf_token": CSRF,
        "station_name": "Engine assembly station 3",
        "alarm_count": 0,
        "simulated": True,
        "page": "",
    }
    base.update(context)
    if template.endswith(".html") and "\n" not in template:
        return _ENV.get_template(template).render(base)
    return _ENV.from_string(template).render(base)


EDITOR_PAGE = """\
{% extends "base.html" %}
{% block title %}Model{% endblock %}
{% block head %}<script src="/static/js/editor.js" defer></script>{% endblock %}
{% block content %}
<div class="page-head"><h1>Model</h1>
  <button class="btn" id="check" hx-post="/check" hx-target="#model-errors" hx-swap="outerHTML"
          hx-include="#model-text">Check</button></div>
<div class="editor" data-editor>
  <textarea name="text" id="model-text" spellcheck="false">{{ text }}</textarea>
</div>
<ul id="model-errors" class="error-list"></ul>
{% endblock %}
"""

TASKS_PAGE = """\
{% extends "base.html" %}
{% import "_macros.html" as ui with context %}
{% block title %}Tasks{% endblock %}
{% block content %}
<ul class="cards">
  <li>{% call ui.card("Place bolts on bolt pair 1", waits=true) %}
    <p>Take two M10 bolts from the kitting MiR and put them in bolt pair 1.</p>
    {{ ui.done_button("/tasks/7/done", {"step": 3}) }}
  {% endcall %}</li>
  <li>{% call ui.card("Tighten bolt pair 1", meta="r1 with the nutrunner") %}
    <p>{{ ui.badge("e") }} {{ ui.badge("i") }} {{ ui.badge("error") }}
       {{ ui.badge("unavailable") }} {{ ui.badge("waiting") }}</p>
  {% endcall %}</li>
</ul>
<ul class="alarm-list">
  {{ ui.alarm_row("critical", "r2 stopped answering", "12:03:11", "/alarms/1/ack") }}
  {{ ui.alarm_row("high", "Nutrunner torque not reached on bp3", "12:01:40", acked=true) }}
  {{ ui.alarm_row("medium", "Tool changer r1: lock time-out", "11:58:02") }}
  {{ ui.alarm_row("low", "Camera r2 found nothing", "11:40:17", cleared=true) }}
</ul>
<table class="table">
  <caption>Operations</caption>
  <thead><tr><th>Operation</th><th>State</th><th>Resource</th></tr></thead>
  <tbody>
    <tr><td data-label="Operation">tighten_bp1_with_r1_and_a_long_name</td>
        <td data-label="State">{{ ui.badge("e") }}</td><td data-label="Resource">r1</td></tr>
    <tr class="is-error"><td data-label="Operation">mount_oil_filter2</td>
        <td data-label="State">{{ ui.badge("error") }}</td>
        <td data-label="Resource">operator</td></tr>
  </tbody>
</table>
{{ ui.pager(2, 5, url_for_page) }}
<div class="diff"><span class="hunk">@@ -12,2 +12,2 @@</span>
<span class="del">-  guard: "r1.pos == home"</span>
<span class="add">+  guard: "r1.pos == home &amp;&amp; !nr.running"</span></div>
<p>{{ ui.button("Reset nutrunner", hx_post="/echo", hx_target="#echo",
               confirm="Reset the nutrunner?", id="reset") }}</p>
<div id="echo"></div>
{% endblock %}
"""


@pytest.fixture(scope="module")
def site() -> Iterator[_Site]:
    """The static files and the test pages on 127.0.0.1, ephemeral port."""
    server = _Site()
    text = "".join(DEMO_MODEL.read_text().splitlines(keepends=True)[:200])
    engineer = SimpleNamespace(name="Erik Engineer", role="engineer")
    operator = SimpleNamespace(name="Olivia Operator-with-a-long-name", role="operator")
    server.pages["/login"] = render("login.html", error="Wrong name or password.")
    server.pages["/password"] = render("login.html", must_change=True)
    server.pages["/model"] = render(EDITOR_PAGE, user=engineer, page="model", text=text)
    server.pages["/tasks"] = render(
        TASKS_PAGE,
        user=operator,
        page="tasks",
        alarm_count=3,
        message="Bolt pair 1 confirmed.",
        url_for_page=lambda n: f"/tasks?page={n}",
    )
    server.pages["/users"] = render(
        '{% extends "base.html" %}{% block content %}<h1>Users</h1>'
        '<p id="ctx">{{ role }}/{{ alarms|join(",") }}/{{ station }}/{{ current }}</p>'
        "{% endblock %}",
        # a page's own variables must survive base.html's
        role="page-role",
        alarms=[1, 2],
        station="page-station",
        current="page-current",
        user=SimpleNamespace(name="Ada Administrator", role="admin"),
        page="users",
        alarm_count=12,
        alarm_priority="medium",
    )
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server
    server.drop_events()
    server.shutdown()
    server.server_close()


@pytest.fixture
def open_page(
    browser: Any, site: _Site, request: pytest.FixtureRequest
) -> Iterator[Callable[..., Any]]:
    """open_page(path, viewport) -> a loaded Playwright page; a screenshot if the test fails."""
    contexts: list[Any] = []
    pages: list[Any] = []
    failed_before = request.session.testsfailed
    site.drop_events(refuse=False)

    def open_(path: str, viewport: dict[str, int] = DESKTOP) -> Any:
        context = browser.new_context(viewport=viewport)
        contexts.append(context)
        page = context.new_page()
        pages.append(page)
        errors: list[str] = []
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.js_errors = errors
        page.goto(site.url + path)
        page.wait_for_load_state("load")
        return page

    yield open_
    if request.session.testsfailed > failed_before:
        SCREENSHOTS.mkdir(exist_ok=True)
        for k, page in enumerate(pages):
            page.screenshot(path=SCREENSHOTS / f"failed-{request.node.name}-{k}.png")
    for context in contexts:
        context.close()


def shot(page: Any, name: str, full_page: bool = False) -> None:
    SCREENSHOTS.mkdir(exist_ok=True)
    page.screenshot(path=SCREENSHOTS / name, full_page=full_page)


# ---- checks ---------------------------------------------------------------------------------

SMALL_TARGETS = """() => {
  const sel = 'button, input:not([type=hidden]), select, textarea, a.btn, .nav a, summary, '
            + '.alarm-count, #model-errors li';
  return [...document.querySelectorAll(sel)]
    .filter((el) => el.getClientRects().length && getComputedStyle(el).visibility !== 'hidden')
    .map((el) => ({el: el.outerHTML.slice(0, 90), ...el.getBoundingClientRect().toJSON()}))
    .filter((r) => r.height < 44 || r.width < 44);
}"""

SMALL_TEXT = """() => {
  const small = [];
  const walker = document.createTreeWalker(document.body, NodeFilter.SHOW_TEXT);
  while (walker.nextNode()) {
    const node = walker.currentNode;
    const el = node.parentElement;
    if (!node.data.trim() || !el.getClientRects().length) continue;
    if (el.closest('.visually-hidden, .skip-link, [hidden]')) continue;
    const size = parseFloat(getComputedStyle(el).fontSize);
    if (size < 16) small.push({text: node.data.trim().slice(0, 40), size});
  }
  return small;
}"""


def assert_fits_watch(page: Any) -> None:
    width = page.evaluate("document.documentElement.scrollWidth")
    assert width <= WATCH["width"], f"horizontal scroll: content is {width} px wide"
    assert page.evaluate(SMALL_TARGETS) == []
    assert page.evaluate(SMALL_TEXT) == []


def test_login_fits_a_watch(open_page: Callable[..., Any]) -> None:
    page = open_page("/login", WATCH)
    assert_fits_watch(page)
    assert page.get_by_role("alert").inner_text() == "Wrong name or password."
    form = page.locator("form[action='/login'][method='post']")
    assert form.locator("input[name=csrf_token]").input_value() == CSRF
    assert form.locator("input[name=name]").is_visible()
    assert form.locator("input[name=password]").is_visible()
    assert page.locator("meta[name=csrf-token]").get_attribute("content") == CSRF
    assert page.locator("body[sse-connect]").count() == 0  # nobody logged in: no event stream
    shot(page, "static-login-watch.png")
    assert page.js_errors == []


def test_password_change_fits_a_watch(open_page: Callable[..., Any]) -> None:
    page = open_page("/password", WATCH)
    assert_fits_watch(page)
    form = page.locator("form[action='/password'][method='post']")
    assert form.locator("input[name=new_password][type=password]").is_visible()
    assert form.locator("input[name=repeat][type=password]").is_visible()
    assert form.locator("input[name=csrf_token]").input_value() == CSRF
    shot(page, "static-password-watch.png")


def test_operator_page_fits_a_watch(open_page: Callable[..., Any], site: _Site) -> None:
    page = open_page("/tasks", WATCH)
    assert_fits_watch(page)
    assert page.locator(".nav-menu").count() == 0  # two links fit: no menu
    assert page.locator("nav.nav a").all_inner_texts() == ["Tasks", "Alarms"]
    assert page.locator("nav.nav a[aria-current=page]").inner_text() == "Tasks"
    done = page.locator(".card--waits .btn--done")
    assert done.bounding_box()["height"] >= 56
    card_box = page.locator(".card--waits").bounding_box()
    assert done.bounding_box()["width"] >= card_box["width"] - 40  # full width of the card
    title_size = page.eval_on_selector(".card__title", "el => getComputedStyle(el).fontSize")
    assert float(title_size.removesuffix("px")) >= 20
    # only abnormal states are coloured
    grey = page.eval_on_selector(".badge--idle", "el => getComputedStyle(el).backgroundColor")
    red = page.eval_on_selector(".badge--error", "el => getComputedStyle(el).backgroundColor")
    assert grey == "rgba(0, 0, 0, 0)"
    assert red == "rgb(192, 0, 0)"
    assert page.locator(".alarm-count--active .alarm-count__n").inner_text() == "3"
    shot(page, "static-tasks-watch.png", full_page=True)
    page.set_viewport_size(DESKTOP)
    shot(page, "static-tasks-desktop.png", full_page=True)
    assert page.js_errors == []


def test_long_nav_collapses_to_a_menu_on_a_watch(open_page: Callable[..., Any]) -> None:
    page = open_page("/users", WATCH)
    assert page.locator("#ctx").inner_text() == "page-role/1,2/page-station/page-current"
    assert page.locator(".nav__list").is_hidden()
    menu = page.locator(".nav-menu > summary")
    assert menu.inner_text().replace("\xa0", " ").strip() == "Menu: Users"
    menu.click()
    links = page.locator(".nav-menu a")
    assert links.all_inner_texts() == [
        "Tasks",
        "Alarms",
        "Station",
        "Model",
        "Simulation",
        "Audit",
        "Users",
    ]
    assert page.locator(".nav-menu a[aria-current=page]").inner_text() == "Users"
    assert_fits_watch(page)
    assert page.locator("#alarm-count[data-priority=medium]").inner_text().strip() == "12"
    shot(page, "static-menu-watch.png", full_page=True)
    menu.click()
    page.click(".user-menu > summary")
    panel = page.locator(".user-menu__panel").bounding_box()
    assert panel["x"] >= 0 and panel["x"] + panel["width"] <= WATCH["width"]
    assert page.locator(".user-menu__panel button", has_text="Log out").is_visible()
    assert_fits_watch(page)
    page.keyboard.press("Escape")
    assert page.locator(".user-menu__panel").is_hidden()
    page.set_viewport_size(DESKTOP)
    assert page.locator(".nav-menu").is_hidden()
    assert page.locator(".nav__list a").count() == 7
    assert page.locator(".user-inline button", has_text="Log out").is_visible()
    assert page.js_errors == []


def test_connection_indicator_and_alarm_count_follow_the_event_stream(
    open_page: Callable[..., Any], site: _Site
) -> None:
    page = open_page("/tasks", WATCH)
    page.wait_for_selector("#conn[data-state=live]")
    assert page.locator("#conn").inner_text().strip() == "live"
    site.push_event("alarm", json.dumps({"count": 0}))
    page.wait_for_selector("#alarm-count:not(.alarm-count--active)")
    assert page.locator("#alarm-count .alarm-count__n").inner_text() == "0"
    site.push_event("alarm", json.dumps({"count": 2, "priority": "high"}))
    page.wait_for_selector("#alarm-count.alarm-count--active[data-priority=high]")
    site.drop_events(refuse=True)
    page.wait_for_selector("#conn[data-state=down]")
    assert page.locator("#conn").inner_text().strip() == "disconnected"
    shot(page, "static-disconnected-watch.png")


def test_htmx_requests_carry_csrf_and_data_confirm_asks(
    open_page: Callable[..., Any], site: _Site
) -> None:
    page = open_page("/tasks", DESKTOP)
    page.wait_for_function("window.htmx !== undefined")
    site.csrf_headers.clear()
    page.once("dialog", lambda dialog: dialog.dismiss())
    page.click("#reset")
    page.wait_for_timeout(300)
    assert site.csrf_headers == []  # declined: no request
    page.once("dialog", lambda dialog: dialog.accept())
    page.click("#reset")
    page.wait_for_selector("#echo-result")
    assert page.locator("#echo-result").inner_text() == f"token {CSRF}"
    assert site.csrf_headers == [CSRF]


# ---- the editor -----------------------------------------------------------------------------

MARKED = """() => ({
  lines: [...document.querySelectorAll('.editor-line')]
    .map((el, i) => el.classList.contains('is-error') ? i + 1 : 0).filter(Boolean),
  gutter: [...document.querySelectorAll('.editor-ln.is-error')].map((el) => +el.textContent),
  notes: [...document.querySelectorAll('.editor-note')].map((el) => el.textContent),
})"""


def open_editor(open_page: Callable[..., Any]) -> Any:
    page = open_page("/model", DESKTOP)
    page.wait_for_selector(".editor--on .editor-line")
    return page


def mirror_matches(page: Any) -> bool:
    return page.evaluate(
        "document.querySelector('.editor-code').textContent"
        " === document.querySelector('#model-text').value"
    )


def test_editor_highlights_and_mirrors_the_text(open_page: Callable[..., Any]) -> None:
    page = open_editor(open_page)
    for kind in ("key", "comment", "str", "op", "dash", "bool", "punct"):
        assert page.locator(f".editor-code .tok-{kind}").count() > 0, kind
    assert mirror_matches(page)
    lines = page.evaluate("document.querySelector('#model-text').value.split('\\n').length")
    assert page.locator(".editor-line").count() == lines
    assert page.locator(".editor-ln").count() == lines
    # layered exactly: line n of the mirror sits where the textarea draws line n
    geometry = page.evaluate("""() => {
      const lines = document.querySelectorAll('.editor-line');
      const ta = document.querySelector('#model-text');
      const st = getComputedStyle(ta);
      const mirror = getComputedStyle(document.querySelector('.editor-mirror'));
      return {top: lines[149].offsetTop, lh: parseFloat(st.lineHeight), font: st.font,
              mirrorFont: mirror.font, padding: st.padding, mirrorPadding: mirror.padding,
              height: lines[lines.length - 1].offsetTop + lines[lines.length - 1].offsetHeight,
              scroll: ta.scrollHeight, pad: parseFloat(st.paddingTop)};
    }""")
    assert geometry["font"] == geometry["mirrorFont"]
    assert geometry["padding"] == geometry["mirrorPadding"]
    assert geometry["top"] == 149 * geometry["lh"]
    assert geometry["height"] + 2 * geometry["pad"] == geometry["scroll"]
    # the highlighter escapes markup
    html = page.evaluate("window.sequenceEditor.highlightLine('a: \"<b> & c\" # <i>')")
    assert "<b>" not in html and "<i>" not in html
    assert "&lt;b&gt; &amp; c" in html
    # the textarea scrolls, the mirror and gutter follow
    page.eval_on_selector("#model-text", "ta => { ta.scrollTop = 1000; }")
    # the scroll event comes when the browser gets to it (later on a busy machine)
    page.wait_for_function(
        "() => document.querySelector('.editor-code').style.transform"
        " === 'translate(0px, -1000px)'",
        timeout=10_000,
    )
    assert page.js_errors == []


def eventually(check: Callable[[], bool], seconds: float = 10.0) -> None:
    """Poll `check` (the editor re-highlights after a short debounce, later on a busy machine)."""
    import time

    deadline = time.monotonic() + seconds
    while not check():
        assert time.monotonic() < deadline, "not within the time limit"
        time.sleep(0.05)


def test_editor_marks_errors_far_down(open_page: Callable[..., Any]) -> None:
    page = open_editor(open_page)
    page.evaluate(
        "window.sequenceEditor.markErrors([{line: 150, column: 3, message: 'unknown variable'}])"
    )
    assert page.evaluate(MARKED) == {"lines": [150], "gutter": [150], "notes": ["unknown variable"]}
    note = page.locator(".editor-note")
    assert note.is_visible()
    box = note.bounding_box()
    assert box is not None and box["width"] > 0 and box["height"] > 0
    # in the layout's flow, under the code: it takes the code's room and covers no line of it
    body = page.locator(".editor-body").bounding_box()
    assert box["y"] >= body["y"] + body["height"] - 1
    assert box["y"] >= 0 and box["y"] + box["height"] <= DESKTOP["height"]
    line = page.locator(".editor-line").nth(149).bounding_box()
    assert line["y"] + line["height"] <= body["y"] + body["height"]  # the line shows whole
    editor = page.locator("[data-editor]").bounding_box()
    assert box["y"] + box["height"] <= editor["y"] + editor["height"] + 1
    shot(page, "static-editor.png")

    # typing above the error moves the mark with its line; the mirror stays exact
    page.evaluate("window.sequenceEditor.goTo(10, 1)")
    page.keyboard.type('- {name: new.var, domain: bool, guard: "a && !b"}')
    page.keyboard.press("Enter")
    eventually(lambda: mirror_matches(page))  # highlighting is debounced while typing
    eventually(lambda: page.evaluate(MARKED)["lines"] == [151])
    eventually(lambda: page.locator(".editor-line").nth(9).locator(".tok-op").count() == 2)
    # an opened quote re-highlights the following lines, closing it restores them
    page.evaluate("window.sequenceEditor.goTo(44, 1)")  # "variables:", one line down now
    page.keyboard.type('"')
    eventually(lambda: page.locator(".editor-line").nth(44).locator(".tok-key").count() == 0)
    page.keyboard.press("Backspace")
    eventually(lambda: page.locator(".editor-line").nth(44).locator(".tok-key").count() > 0)
    eventually(lambda: mirror_matches(page))
    # Tab inserts two spaces and keeps the focus
    before = page.eval_on_selector("#model-text", "ta => ta.value.length")
    page.keyboard.press("Tab")
    assert page.eval_on_selector("#model-text", "ta => ta.value.length") == before + 2
    assert page.evaluate("document.activeElement.id") == "model-text"
    # markup typed in the model is text in the mirror
    page.keyboard.type("# <script>alert(1)</script> & <b>")
    eventually(lambda: mirror_matches(page))
    assert page.locator(".editor-code script, .editor-code b").count() == 0
    assert page.js_errors == []


def test_editor_follows_swapped_error_list(open_page: Callable[..., Any], site: _Site) -> None:
    page = open_editor(open_page)
    page.evaluate("window.sequenceEditor.markErrors([{line: 150, column: 3, message: 'old'}])")
    # what htmx does: replace #model-errors, then dispatch htmx:afterSwap
    page.evaluate("""() => {
      const fresh = document.createElement('ul');
      fresh.id = 'model-errors';
      fresh.innerHTML = '<li data-line="20" data-column="5">unknown variable r3.pos</li>'
                      + '<li data-line="120" data-column="1">guard never holds</li>';
      document.querySelector('#model-errors').replaceWith(fresh);
      fresh.dispatchEvent(new CustomEvent('htmx:afterSwap', {bubbles: true}));
    }""")
    marked = page.evaluate(MARKED)
    assert marked["lines"] == [20, 120]
    assert marked["gutter"] == [20, 120]
    assert marked["notes"] == ["unknown variable r3.pos", "guard never holds"]
    assert page.locator(".editor-note").first.is_visible()

    # a real htmx swap from the server (with the CSRF header), then a click on an error
    # (on a line of the model long enough for its column)
    at = next(
        n
        for n, text in enumerate(DEMO_MODEL.read_text().splitlines(), 1)
        if n >= 40 and len(text) >= 10
    )
    site.check_fragment = (
        '<ul id="model-errors" class="error-list">'
        f'<li data-line="{at}" data-column="7">'
        "expected a list of actions &amp; got &lt;str&gt;</li></ul>"
    )
    site.csrf_headers.clear()
    page.click("#check")
    page.wait_for_function("document.querySelectorAll('.editor-line.is-error').length === 1")
    assert page.evaluate(MARKED) == {
        "lines": [at],
        "gutter": [at],
        "notes": ["expected a list of actions & got <str>"],
    }
    assert site.csrf_headers == [CSRF]
    page.click("#model-errors li")
    caret = page.evaluate("""() => {
      const ta = document.querySelector('#model-text');
      const before = ta.value.slice(0, ta.selectionStart).split('\\n');
      return {focused: document.activeElement === ta, line: before.length,
              column: before[before.length - 1].length + 1};
    }""")
    assert caret == {"focused": True, "line": at, "column": 7}

    # an empty list clears the marks
    site.check_fragment = '<ul id="model-errors" class="error-list"></ul>'
    page.click("#check")
    page.wait_for_function("document.querySelectorAll('.editor-line.is-error').length === 0")
    assert page.evaluate(MARKED) == {"lines": [], "gutter": [], "notes": []}
    assert page.js_errors == []
