"""Scene state model shared by the protocol, scene files and the renderer."""

from .files import dumps_scene, load_scene, resolve_scene_path, save_scene
from .model import Camera, Effect, Entity, Light, Scene
from .patch import apply_patch, at_sim_time, deep_merge, patch_from_assignments

__all__ = [
    "Camera", "Effect", "Entity", "Light", "Scene",
    "apply_patch", "at_sim_time", "deep_merge", "patch_from_assignments",
    "dumps_scene", "load_scene", "resolve_scene_path", "save_scene",
]
