"""The API's documentation page, /docs, served only with `sp serve --api-docs` (with
/openapi.json; there is no /redoc).

FastAPI's own page loads an unpinned Swagger UI from a CDN and starts it with an inline
script; this one loads the pinned copy vendored under static/vendor/ (its version, licence
and sha256 in static/vendor/README.md) and starts it with static/js/api-docs.js, so its policy
(app.web.headers.DOCS_POLICY) allows only the station's own files.  static/css/api-docs.css
darkens Swagger UI's light colours to a readable contrast.
"""

from __future__ import annotations

from fastapi import APIRouter
from fastapi.responses import HTMLResponse

router = APIRouter(include_in_schema=False)
SWAGGER_UI = "5.36.0"  # swagger-ui-dist, vendored
DOCS = "/docs"
PAGE = f"""<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>Sequence Planner station: API</title>
<link rel="icon" href="/favicon.ico">
<link rel="stylesheet" href="/static/vendor/swagger-ui-{SWAGGER_UI}.css">
<link rel="stylesheet" href="/static/css/api-docs.css">
</head>
<body>
<div id="swagger-ui"></div>
<script src="/static/vendor/swagger-ui-bundle-{SWAGGER_UI}.js"></script>
<script src="/static/js/api-docs.js"></script>
</body>
</html>
"""


@router.get(DOCS)
def api_docs() -> HTMLResponse:
    return HTMLResponse(PAGE)
