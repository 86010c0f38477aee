"""The demo and its HTML report (``retime demo``)."""
