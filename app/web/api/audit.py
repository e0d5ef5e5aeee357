"""The audit log through the API: filtered as on the audit page (app.web.audit_log), newest
first, in pages (permission `audit`)."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated, Any

from fastapi import APIRouter, Query
from pydantic import BaseModel, Field

from app.store import audit
from app.store.tables import AuditRecord
from app.web.api.common import BEARER, PREFIX, errors
from app.web.audit_log import detail_of
from app.web.deps import AuditCriteria, AuditReader, StoreDep
from app.web.limits import MAX_PAGE

router = APIRouter(prefix=PREFIX, tags=["audit"], dependencies=BEARER)


class AuditRecordOut(BaseModel):
    id: int
    time: datetime
    station: str
    user: str
    kind: str
    subject: str
    resource: str
    detail: dict[str, Any]
    hash: str


class AuditPageOut(BaseModel):
    records: list[AuditRecordOut] = Field(description="newest first")
    total: int = Field(description="records that match the filter")
    page: int
    pages: int
    page_size: int


def record_out(record: AuditRecord) -> AuditRecordOut:
    return AuditRecordOut(
        id=record.id,
        time=datetime.fromtimestamp(record.time, UTC),
        station=record.station,
        user=record.user,
        kind=record.kind,
        subject=record.subject,
        resource=record.resource,
        detail=detail_of(record),
        hash=record.hash,
    )


@router.get(
    "/audit",
    summary="The audit log, filtered, newest first, in pages",
    responses=errors(401, 403, 422),
)
def get_audit(
    _caller: AuditReader,
    store: StoreDep,
    chosen: AuditCriteria,
    page: Annotated[int, Query(ge=1, le=MAX_PAGE, description="1-based")] = 1,
) -> AuditPageOut:
    """The same filter as the audit page.  A page past the end gives the last page.  Needs
    `audit`."""
    with store.sessions() as session:
        found = audit.page_of(session, chosen.where, page)
        records = [record_out(r) for r in found.records]
    return AuditPageOut(
        records=records,
        total=found.total,
        page=found.page,
        pages=found.pages,
        page_size=audit.PAGE_SIZE,
    )
