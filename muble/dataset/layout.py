"""The dataset's file layout, re-exported from ``muble.core.layout`` (episode sources read stored datasets too)."""
from muble.core.layout import PREFIX, SPLIT_NAME, DatasetLayout, check_split_name

__all__ = ["PREFIX", "SPLIT_NAME", "DatasetLayout", "check_split_name"]
