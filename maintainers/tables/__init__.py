"""The generated Markdown tables (``python -m maintainers tables``): each regenerates from the committed runs
and goes between its markers (``report/markdown.replace_block``); a test fails when one is stale."""
