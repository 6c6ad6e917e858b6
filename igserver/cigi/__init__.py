"""CIGI 3.3 (SISO-STD-013) over UDP beside protocol v1: packets, their mapping onto the one scene state,
the listener in the serve process (docs/cigi.md)."""
