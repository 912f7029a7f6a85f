"""Dataset production at scale: deterministic per-index work, atomic outputs, resumable shards, executors."""
