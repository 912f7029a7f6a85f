"""The plugins the built-in generator config (muble_conf/generator/shopvrb2.yaml) names, for generators in tests."""
from muble_conf import group_defaults

BUILTIN = {k: v for k, v in group_defaults("generator", "shopvrb2").items()
           if k in ("renderer", "renderer_options", "reach_primitive")}
