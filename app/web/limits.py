"""How big a request and each of its fields may be, for the pages and the API alike.

A bound at the edge turns junk into a 422 that names the field (or a 413 for a body) before
any handler, the runner or the store sees it.  Text fields are held to the width of the
column that keeps them (app.store.tables) or to what a person can usefully type.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import StringConstraints

BODY_BYTES = 1024 * 1024  # a request body past this is refused (413) before it is parsed

MAX_MODEL_CHARS = 2_000_000
# what a request carrying a model may be: the text URL- or JSON-encoded (every other request
# is held to BODY_BYTES), and the form field once decoded (UTF-8)
MODEL_BODY_BYTES = 8 * 1024 * 1024
MODEL_FORM_LIMITS = {"max_part_size": 4 * MAX_MODEL_CHARS}
# the largest version number a request may name: beyond 64 bits SQLite raises OverflowError
MAX_VERSION = 1_000_000_000
MAX_PAGE = 1_000_000_000  # an audit page number, for the same reason
MAX_RUN = 2**62  # a run's first record id (the timeline's `run`)

NAME_CHARS = 200  # a name in the model: intention, operation, transition, variable
VALUE_CHARS = 200  # a variable's value, as the station's form sends it
API_VALUE_CHARS = 100  # the same, in the API's body
NOTE_CHARS = 500  # a person's note or reason
CONFIRM_CHARS = 20  # a form's confirmation flag
CARD_CHARS = 100  # a command card's value
MAX_STEP = 10_000  # a recovery plan's step
MAX_PLAN_STEPS = 1_000  # the steps of a recovery plan approved at once
# a step of a recovery plan, as the approval card names it (the form's and the API's)
StepName = Annotated[str, StringConstraints(min_length=1, max_length=NAME_CHARS)]
KEY_CHARS = 200  # an alarm's key, as the store keeps it (AlarmRecord.key)
MOST_KEYS = 1000  # alarms one "acknowledge all" may name
SHELVE_MINUTES = 480  # the alarm page's shelve (the API's: app.station.alarms.SHELVE_LIMIT)
EXPERIMENT_CHARS = 100  # an experiment's id

USER_CHARS = 64  # a user name (User.name, AuditRecord.user)
PASSWORD_CHARS = 200
ROLE_CHARS = 16  # User.role
NEXT_CHARS = 2000  # where the sign-in form goes next

# the audit filter's values: the columns' widths (AuditRecord), a time, the `show` switch
KIND_CHARS, RESOURCE_CHARS, STATION_CHARS, TEXT_CHARS = 32, 64, 64, 200
TIME_CHARS = 64
SHOW_CHARS = 16
