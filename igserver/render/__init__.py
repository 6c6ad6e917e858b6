"""Rendering: EGL context, FrameGraph of passes, render process."""
