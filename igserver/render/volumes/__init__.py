"""Fire and smoke: effect state (effects), profiles, the volume pass (volumes: its march;
modelling: its 3D textures; settings: its knobs), fire flicker lights."""
