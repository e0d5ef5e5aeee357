"""The papers' vocabulary as plain data: expressions, the flat model, the station form, the
step semantics.  Nothing here reads files or plans; `planner.reading` builds these values
from YAML and `planner.planning.query` plans over them."""
