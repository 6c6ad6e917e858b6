"""Fire and smoke: effect state (effects), profiles, the volume pass (volumes), fire flicker lights."""
