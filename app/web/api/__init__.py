"""The JSON API under /api: what the pages do, for line systems (MES) and scripts; one
router per area (app.web.app includes each by name), each with its request and answer
schemas beside its routes, and what they share in `common` and `schemas`.

Authenticate with `POST /api/token` and send `Authorization: Bearer <token>`; a browser
session works too (with its CSRF token on unsafe methods).  Each route names the
permission it needs (app.people.auth.PERMISSIONS).  Names are checked before the runner sees
them (404 with a suggestion); the runner then takes or refuses the action (409 with its
reason); bodies that do not fit the schema are 422.  Actions answer with the runner's events
of the tick that carried them out, so the caller sees what happened.
"""
