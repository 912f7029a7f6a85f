"""The action loop: an agent acts in a world (symbolic or physical) until done, judged into an ``Outcome``."""
from muble.episode.loop import EpisodeMonitor, EpisodeResult, StepRecord, World, run_episode

__all__ = ["EpisodeMonitor", "EpisodeResult", "StepRecord", "World", "run_episode"]
