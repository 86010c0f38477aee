"""``retime edit``: an interactive timing editor in the browser (McCann et al. 2006 §3.6; Hsu et al.
2007's keytime workflow). ``server.create_app`` builds the web app; ``sessions`` holds the per-tab
state; ``methods`` adapts each timing method (curve in, curve out). The front end is built from
``web/`` into ``static/`` and shipped with the package."""
