"""Protocol v1: the FastAPI app (REST, MJPEG, WebSocket), its codec, problem errors and metrics.

``create_app`` builds the app around a ``RenderService``; ``serve`` runs it under uvicorn.
"""
