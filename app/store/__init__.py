"""The station's durable store: SQLAlchemy 2 tables, the engine, the append-only audit log."""
