"""The API's documentation (issue 26): off by default; with `sp serve --api-docs`, /docs is
the pinned Swagger UI vendored under static/vendor/, started by a file of the station's own,
under a policy that allows no inline script or style and nothing from elsewhere.  (That it
renders without a policy violation: tests/browser/test_browser_api_docs.py.)"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from app.cli.arguments import parser
from tests.support.paths import REPOSITORY
from tests.support.stations import RunningStation, start_station

VENDOR = REPOSITORY / "static" / "vendor"
COMMON = "object-src 'none'; base-uri 'none'; frame-ancestors 'none'; form-action 'self'"
# written out, not imported: a policy loosened in app/web/headers.py must fail here
POLICY = f"default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self'; {COMMON}"
DOCS_POLICY = (
    f"default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data:; {COMMON}"
)
FASTAPI_PAGES = ("/docs", "/redoc", "/openapi.json", "/docs/oauth2-redirect")


@pytest.fixture(scope="module")
def documented(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    running = start_station(Path(tmp_path_factory.mktemp("docs")), api_docs=True)
    yield running
    running.stop()


def test_the_documentation_is_off_by_default(station: RunningStation) -> None:
    client = station.client()
    for url in FASTAPI_PAGES:
        answer = client.get(url)
        assert answer.status_code == 404, url
        assert answer.headers["content-security-policy"] == POLICY, url
    assert parser().parse_args(["serve"]).api_docs is False
    assert parser().parse_args(["serve", "--api-docs"]).api_docs is True


def test_with_api_docs_the_page_loads_only_the_stations_own_files(
    documented: RunningStation,
) -> None:
    client = documented.client()
    page = client.get("/docs")
    assert page.status_code == 200
    assert page.headers["content-security-policy"] == DOCS_POLICY
    assert "<style" not in page.text and " style=" not in page.text
    assert re.findall(r"<script(?![^>]*\bsrc=)[^>]*>", page.text) == [], "an inline script"
    assert re.findall(r"<script[^>]*>\s*[^<\s]", page.text) == [], "a script with a body"
    assets = re.findall(r'(?:src|href)="([^"]*)"', page.text)
    assert len(assets) >= 4, assets
    for asset in assets:
        assert asset.startswith("/") and not asset.startswith("//"), asset
        fetched = client.get(asset)
        assert fetched.status_code == 200, asset
        assert fetched.headers["content-security-policy"] == POLICY, asset
    assert any("swagger-ui-bundle-" in a for a in assets)
    schema = client.get("/openapi.json")
    assert schema.status_code == 200 and schema.json()["openapi"].startswith("3.")
    assert schema.headers["content-security-policy"] == POLICY
    for url in ("/redoc", "/docs/oauth2-redirect"):  # FastAPI's other pages stay off
        assert client.get(url).status_code == 404, url


def test_the_vendored_files_are_the_pinned_ones() -> None:
    """Each file in static/vendor/README.md's table has the sha256 written there."""
    table = re.findall(
        r"^\| ([\w.-]+) \| \S+ [^|]*\| ([0-9a-f]{64}) \|$",
        (VENDOR / "README.md").read_text(),
        re.MULTILINE,
    )
    names = {name for name, _ in table}
    assert {"swagger-ui-bundle-5.36.0.js", "swagger-ui-5.36.0.css"} <= names
    for name, digest in table:
        assert hashlib.sha256((VENDOR / name).read_bytes()).hexdigest() == digest, name
    assert "Apache License" in (VENDOR / "LICENSE.swagger-ui").read_text()
