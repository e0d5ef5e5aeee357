"""What the pages show, computed from a station view: task cards and station activity, and
plans drawn with their partial order.  No web framework here (`app.web` renders them)."""
