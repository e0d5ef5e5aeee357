"""The web edge: routers per area (operator, engineer, audit, api), templates, SSE."""
