"""No internal names on any page (issue 16): every page of every role, in a running station at
moments with task cards of each kind, is scanned for the model's identifiers and for
references to the papers.

What counts as an identifier is read off the active model, not listed by hand (`internal_names`):
every name of the model (resources, variables and their values, transitions, abilities,
specifications, operations, intentions, predicates, the station) and each of its dotted parts,
when it is at least two characters long and is not a plain English word: a part with `_`, `.`
or a digit (`bp3`, `r1_tc`, `oil_filters_after_bolts`) always counts; an alphabetic one (`nr`,
`mir`, `pos`) unless it is in `ENGLISH`, the model's names that are ordinary words a page may
say ("home", "operator").  Tokens are compared without case ("R1", "Nr" count).

What a person reads (`TEXT_OF_PAGE`): the title, every text node of the body (also those hidden
until opened, such as a closed <details>), and the attributes people read: title, aria-label,
placeholder, alt and the label of an input button.  Source text shown as such is exempt: the
contents of <code>, <pre>, <kbd>, <samp> and <textarea> (the model editor, a diff).  Identifiers
may stay in attributes nobody reads (name, value, data-*).  Experiment names (E6) may appear:
they name the demo's experiments; an experiment reference in parentheses ("(E6, E7)") may not.
"""

from __future__ import annotations

import re
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import pytest

from planner.model.station import Station
from planner.reading import load_station
from planner.runner import Reject
from tests.browser.test_browser_operator import sign_in_first_time
from tests.support.paths import MINI_STATION, REPOSITORY
from tests.support.stations import REJECT_BUDGET, RunningStation, start_station

ROOT = REPOSITORY
WATCH = {"width": 320, "height": 320}
DESKTOP = {"width": 1280, "height": 800}
ROLES = ("operator", "engineer", "auditor", "admin")

_ENGLISH_WORDS = (
    "arrive at card clear confirm connect connected docked done empty enabled engine executing "
    "failed failure finish finished flange forget found frame goal hanging home idle last "
    "located lock miss missed mounted none operator placed precondition release resetting scan "
    "starting state stop tightened tool torque trigger unknown unlock"
)
ENGLISH = frozenset(_ENGLISH_WORDS.split())
"""The demo model's alphabetic name parts that are plain English, and so may be shown."""

PAPER_REFERENCE = re.compile(
    r"""
    \b[Ss]eed\s*\d{3}\b                                         # seed 000
    | \b(?:Fig(?:ure)?s?\.?|Tables?|Definitions?|Def\.)\s*(?:\d+|[IVX]+\b)   # Figure 6, Table VI
    | \b(?:[Ss]ections?|[Ss]ec\.)\s*\d+(?:\.\d+)*               # section 4.3, sec. 3
    | §\s*\d
    | \bDESIGN\.md\b
    | \(\s*(?:experiments?\s+)?E\d+\b[^)]*\)                    # (E6, E7)
    """,
    re.VERBOSE,
)
_TOKEN = re.compile(r"[A-Za-z0-9_]+(?:\.[A-Za-z0-9_]+)*")


def model_names(station: Station) -> set[str]:
    """Every name the model gives to something."""
    model = station.model
    names = {station.name} | {r.name for r in station.resources}
    names |= {v.name for v in model.variables}
    names |= {str(x) for v in model.variables for x in v.domain if not isinstance(x, bool)}
    names |= {t.name for t in model.transitions} | {s.name for s in model.specifications}
    names |= {o.name for o in station.operations} | {i.name for i in station.intentions}
    names |= {a.qualified for a in station.abilities} | {a.template for a in station.abilities}
    names |= set(station.predicates)
    return names - {""}


def internal_names(station: Station) -> frozenset[str]:
    """The identifiers no page may show, lower case (see the module docstring)."""
    parts = {p for name in model_names(station) for p in (name, *name.split("."))}
    return frozenset(
        p.lower()
        for p in parts
        if len(p) >= 2 and (re.search(r"[_.\d]", p) or p.lower() not in ENGLISH)
    )


def offences(text: str, forbidden: frozenset[str]) -> list[str]:
    """The identifiers and paper references in one piece of text, as found."""
    found = [m.group(0) for m in PAPER_REFERENCE.finditer(text)]
    for token in _TOKEN.findall(text):
        if any(p.lower() in forbidden for p in (token, *token.split("."))):
            found.append(token)
    return found


TEXT_OF_PAGE = """() => {
  const exempt = "script, style, noscript, template, code, pre, kbd, samp, textarea";
  const texts = [document.title];
  const walker = document.createTreeWalker(document.body, NodeFilter.SHOW_TEXT);
  for (let node = walker.nextNode(); node; node = walker.nextNode()) {
    if (node.parentElement && node.parentElement.closest(exempt)) continue;
    const text = node.nodeValue.replace(/\\s+/g, " ").trim();
    if (text) texts.push(text);
  }
  const buttons = "input[type=submit], input[type=button]";
  const read = "[title], [aria-label], [placeholder], [alt], " + buttons;
  for (const element of document.body.querySelectorAll(read)) {
    if (element.closest(exempt)) continue;
    for (const name of ["title", "aria-label", "placeholder", "alt"]) {
      const value = element.getAttribute(name);
      if (value) texts.push(value);
    }
    if (element.matches(buttons) && element.value) {
      texts.push(element.value);
    }
  }
  return texts;
}"""


def page_texts(page: Any) -> list[str]:
    page.wait_for_function("() => !document.querySelector('.htmx-request')")
    texts: list[str] = page.evaluate(TEXT_OF_PAGE)
    return texts


# ---- the scanner itself, on known texts -------------------------------------------------------


@pytest.fixture(scope="module")
def demo_names() -> frozenset[str]:
    model = ROOT / "models" / "demo_station.yaml"
    return internal_names(load_station(model.read_text(), str(model)))


LEAKS = [
    ("Place bp3 on the frame", ["bp3"]),
    ("Robot 2 takes nr", ["nr"]),
    ("The station is in a forbidden state (oil_filters_after_bolts)", ["oil_filters_after_bolts"]),
    ("Done: operator.remove_oil_filters", ["operator.remove_oil_filters"]),
    ("Every bolt pair tightened (seed 000 Figure 6)", ["seed 000", "Figure 6"]),
    ("Failed: r2 docks onto the nutrunner (operation get_nr_r2)", ["r2", "get_nr_r2"]),
    ("demo_station", ["demo_station"]),
    ("Nr.run_nut", ["Nr.run_nut"]),
    ("R1 takes the tool from the MiR", ["R1", "MiR"]),
    ("Move robot 2 home by hand (E6, E7)", ["(E6, E7)"]),
    ("as in section 4.3 and Table VI", ["Table VI", "section 4.3"]),
    ("where r1 is: nr hang", ["r1", "nr"]),
]
CLEAN = [
    "Place bolt pair 3 on the ladder frame",
    "Robot 2 takes the nutrunner",
    "Take off the oil filters mounted too early",
    "Engine assembly · operator",
    "E6: robot 2 stops answering above the engine",
    "Version 2 is active now. 3 tasks done today, 12:40",
    "The operator moves robot 1 home",
]


@pytest.mark.parametrize(("text", "expected"), LEAKS)
def test_the_scan_finds_identifiers_and_references(
    text: str, expected: list[str], demo_names: frozenset[str]
) -> None:
    assert sorted(offences(text, demo_names)) == sorted(expected)


@pytest.mark.parametrize("text", CLEAN)
def test_the_scan_leaves_words_alone(text: str, demo_names: frozenset[str]) -> None:
    assert offences(text, demo_names) == []


def test_the_identifiers_come_from_the_model(demo_names: frozenset[str]) -> None:
    # names and their parts, without case; the English parts left out
    assert {"bp3", "bp3.state", "nr", "mir", "r1_tc", "get_nr_r2", "demo_station"} <= demo_names
    assert {"is_running", "oil_filters_after_bolts", "tighten_bolts", "nr_hang"} <= demo_names
    assert not {"state", "operator", "home", "tool", "engine"} & demo_names
    mini = load_station(MINI_STATION.read_text())
    assert mini.name.lower() in internal_names(mini) and "bp3" not in internal_names(mini)


PAGE = """<!doctype html><title>Tasks · bp3</title><body>
<h1>Bolt pair <b>3</b></h1><details><summary>Why</summary>r2 stopped answering</details>
<p hidden>waits for get_nr_r2</p>
<button name="transition" value="operator.move_r2_home" data-step="r1.goto_bp3"
        aria-label="Done: nr">Done</button>
<input type="submit" value="Approve tighten_bp1"><input name="x" placeholder="note on mir">
<svg><title>oil_ee</title></svg>
<pre>r1.pos == home</pre><code>bp4</code><textarea>agv.engine</textarea>
<script>const shown = "bp2";</script>
</body>"""


def test_the_page_text_is_what_people_read(browser: Any, demo_names: frozenset[str]) -> None:
    context = browser.new_context()
    try:
        page = context.new_page()
        page.set_content(PAGE)
        texts = page_texts(page)
    finally:
        context.close()
    found = sorted(o for t in texts for o in offences(t, demo_names))
    # title, hidden and folded text, read attributes; not name/value/data-*, code or scripts
    assert found == ["bp3", "get_nr_r2", "mir", "nr", "oil_ee", "r2", "tighten_bp1"]


# ---- every page of every role, in a running station ---------------------------------------


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    running = start_station(tmp_path_factory.mktemp("names"), planning_budget=REJECT_BUDGET)
    running.serve()
    yield running
    running.stop()


def _routes(routes: Any, prefix: str = "") -> Iterator[tuple[str, set[str]]]:
    for route in routes:
        if hasattr(route, "original_router"):  # an included router
            yield from _routes(route.original_router.routes, prefix + route.include_context.prefix)
        elif hasattr(route, "path"):
            yield prefix + route.path, set(getattr(route, "methods", None) or ())


NOT_PAGES = ("/api/", "/static", "/docs", "/redoc", "/openapi", "/events", "/healthz", "/favicon")


def page_paths(station: RunningStation) -> list[str]:
    """Every page a person opens: the app's GET routes without parameters in the path, less
    the API, assets, event streams, downloads and the fragments pages load into themselves."""
    paths = {
        path
        for path, methods in _routes(station.built.app.routes)
        if "GET" in methods
        and "{" not in path
        and not path.startswith(NOT_PAGES)
        and "/fragments/" not in path
        and not path.endswith((".csv", ".json", ".ico"))
        and path not in ("/login", "/model/diff")  # /login: before sign-in; the diff: below
    }
    return [*sorted(paths), "/model/diff?version=1"]


@dataclass
class Reader:
    """One person's browser, signed in, and the pages it may open."""

    role: str
    page: Any
    viewport: str
    paths: list[str]


@dataclass
class Seen:
    phrase: str  # the first phrase it was seen in
    moment: str
    readers: set[str]


@dataclass
class Findings:
    """What the scan found: per page, each offending token once, with an example."""

    forbidden: frozenset[str]
    found: dict[str, dict[str, Seen]]  # path → token → where it was first seen
    visited: set[str]

    def scan(self, path: str, reader: str, moment: str, texts: list[str]) -> None:
        self.visited.add(path)
        for text in texts:
            for token in offences(text, self.forbidden):
                seen = self.found.setdefault(path, {}).setdefault(
                    token, Seen(_around(text, token), moment, set())
                )
                seen.readers.add(reader)

    def report(self, most: int = 15) -> str:
        count = sum(len(tokens) for tokens in self.found.values())
        lines = [
            f"{count} model identifiers or paper references on {len(self.found)} of "
            f"{len(self.visited)} pages; per page, each with the first phrase it was seen in:"
        ]
        for path in sorted(self.found):
            tokens = self.found[path]
            readers = sorted({r for seen in tokens.values() for r in seen.readers})
            lines.append(f"  {path}  (read by {', '.join(readers)}; {len(tokens)} found)")
            for token, seen in sorted(tokens.items())[:most]:
                lines.append(f"    {token!r} in “{seen.phrase}”  [{seen.moment}]")
            if len(tokens) > most:
                lines.append(f"    … and {len(tokens) - most} more")
        return "\n".join(lines)


def _around(text: str, found: str, width: int = 90) -> str:
    """The phrase around `found`, at most `width` characters."""
    if len(text) <= width:
        return text
    at = max(text.find(found), 0)
    start = max(0, min(at - width // 3, len(text) - width))
    return ("…" if start else "") + text[start : start + width] + "…"


def _visit(reader: Reader, station: RunningStation, findings: Findings, moment: str) -> None:
    """Every page of `reader.paths` it may open, scanned; those it may not are dropped from
    its paths (refused, or sent elsewhere: an auditor's / is the audit log)."""
    kept = []
    for path in reader.paths:
        answer = reader.page.goto(station.url + path)
        shown = reader.page.url.removeprefix(station.url)
        if answer is None or answer.status != 200 or shown != path:
            continue
        kept.append(path)
        who = reader.role + (" on a watch" if reader.viewport == "watch" else "")
        findings.scan(path, who, moment, page_texts(reader.page))
    reader.paths = kept


@contextmanager
def operator_hands(station: RunningStation) -> Iterator[None]:
    """The operator taps Done on every watch card meanwhile, as one would (in a thread, so
    that the station works on while the browsers sign in and read)."""
    from app.pages.cards import CardKind, task_cards

    stop = threading.Event()

    def tap() -> None:
        while not stop.wait(0.05):
            for card in task_cards(station.live.view):
                if card.kind is CardKind.COMMAND:
                    station.live.confirm_card("operator", card.card).result(10)

    thread = threading.Thread(target=tap, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(10)


def _sign_in(page: Any, station: RunningStation, name: str) -> None:
    sign_in_first_time(page, station.url, name)
    station.changed.add(name)


def _cards_until(
    station: RunningStation, wanted: Callable[[Any], bool], seconds: float = 60.0
) -> list[Any]:
    """The task cards once one of them is `wanted`."""
    from app.pages.cards import task_cards

    found: list[Any] = []

    def shown() -> bool:
        found[:] = task_cards(station.live.view)
        return any(wanted(c) for c in found)

    station.wait(shown, seconds)
    return found


def _play(station: RunningStation, experiment: str) -> None:
    title, scenario = station.built.server.experiments[experiment]
    station.live.play_experiment(scenario, title, "engineer").result(10)


def test_no_page_shows_model_identifiers_or_paper_references(
    station: RunningStation, browser: Any
) -> None:
    findings = Findings(internal_names(station.live.view.model.station), {}, set())
    paths = page_paths(station)
    assert {"/", "/alarms", "/station", "/model", "/simulation", "/audit", "/users"} <= set(paths)
    contexts = []
    readers: list[Reader] = []

    def scan(moment: str, roles: tuple[str, ...]) -> None:
        for reader in readers:
            if reader.role in roles:
                _visit(reader, station, findings, moment)

    with operator_hands(station):
        try:
            # E6: r2 stops answering above the engine; a maintenance card for the operator
            _play(station, "e6_r2_disconnects_above_engine")
            anonymous = browser.new_context(viewport=DESKTOP)
            contexts.append(anonymous)
            page = anonymous.new_page()
            page.goto(station.url + "/login")
            findings.scan("/login", "anyone", "before signing in", page_texts(page))
            for role in ROLES:
                sizes = [("watch", WATCH), ("desktop", DESKTOP)] if role == "operator" else []
                for name, viewport in sizes or [("desktop", DESKTOP)]:
                    context = browser.new_context(viewport=viewport)
                    contexts.append(context)
                    page = context.new_page()
                    page.set_default_timeout(15_000)
                    if name == "watch" or role != "operator":
                        _sign_in(page, station, role)
                    else:  # the operator's second device, in the same session
                        context.add_cookies(readers[0].page.context.cookies())
                    readers.append(Reader(role, page, name, list(paths)))
            _cards_until(station, lambda c: c.transition == "operator.move_r2_home")
            scan("E6 maintenance card", ("operator", "engineer"))
            # E2: oil filters mounted too early; the way out is the operator's own step ...
            _play(station, "e2_oil_filter_early")
            removal = "operator.remove_oil_filters"
            cards = _cards_until(station, lambda c: c.transition == removal)
            scan("E2 forbidden-state instruction", ("operator",))
            # ... which the operator rejects: the station's own steps then wait for approvals
            step = next(c.step for c in cards if c.transition == removal)
            station.live.act(Reject(user="operator", step=step)).result(10)
            _cards_until(station, lambda c: c.kind == "approval")
            scan("E2 approval after a reject", ROLES)
        finally:
            for context in contexts:
                context.close()
    assert len(findings.visited) >= 8, findings.visited  # the scan saw the pages
    if findings.found:
        pytest.fail(findings.report(), pytrace=False)
