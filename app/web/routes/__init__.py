"""The HMI's pages, one router per area (app.web.app includes each by name).

Each module holds its area's routes and what only they show; what every page uses is in
app.web.pages, what a handler may be given (the caller with a permission, the live station,
the store) in app.web.deps.  A module here imports no other module here but one: the station
controls answer with parts of the station pages (`control` → `station`).
"""
