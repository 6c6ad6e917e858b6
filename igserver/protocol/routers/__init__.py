"""Routers of protocol v1, one per concern (FastAPI's "bigger applications" layout)."""
