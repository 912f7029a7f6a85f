"""The ``llm`` agent: a planner behind any OpenAI-compatible chat-completions endpoint (vLLM, Ollama, llama.cpp,
LM Studio, hosted APIs).

Each step it renders the prompt files (``prompts/system.md``, ``prompts/step.md``, or the user's own) from the
instruction, the observed scene, the registered primitives, the last result and a bounded history, asks the
endpoint for one JSON decision and turns it into an ``ActionCall``, an ``Answer`` or a stop. Every reply is kept in
the LLM ledger (``ledger``), so a run resumed or run again replays it instead of asking again. Needs the ``openai``
client (``pip install "muble[llm]"``); the module loads only when the registry builds the agent.
"""
from muble import PluginRecord, hookimpl


@hookimpl
def muble_register_agents() -> list[PluginRecord]:
    from muble_plugins.llm.agent import LlmAgent
    from muble_plugins.llm.config import LlmConfig

    return [PluginRecord("llm", LlmAgent, "asks an OpenAI-compatible chat endpoint for each primitive (JSON replies)",
                         LlmConfig, takes_config=True)]
