"""Files a browser asks for at fixed addresses, outside /static: the station's icon.

Browsers fetch /favicon.ico on their own; without it every first page load logged a 404.
The icon is static/favicon.ico (32 x 32, a PNG inside), cached for a day.
"""

from __future__ import annotations

from fastapi import APIRouter
from fastapi.responses import FileResponse

from app.web.server import STATIC

router = APIRouter(include_in_schema=False)
ICON = STATIC / "favicon.ico"


@router.get("/favicon.ico")
def favicon() -> FileResponse:
    return FileResponse(
        ICON, media_type="image/x-icon", headers={"Cache-Control": "public, max-age=86400"}
    )
