"""Channels across GPUs and machines: channel render workers as Ray actors behind one front server
(docs/cluster.md). Ray is an optional extra (``igserver[cluster]``): nothing here imports it at module
level, and the single-machine IG never imports this package's service."""
