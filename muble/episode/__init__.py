"""The action loop: an agent acts in a world (symbolic or physical) until done, judged into an ``Outcome``."""
from muble.episode.loop import DEFAULT_MAX_STEPS, EpisodeMonitor, EpisodeResult, StepRecord, World, run_episode

__all__ = ["DEFAULT_MAX_STEPS", "EpisodeMonitor", "EpisodeResult", "StepRecord", "World", "run_episode"]
