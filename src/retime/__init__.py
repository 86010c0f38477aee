"""retime: change the timing of character motion without touching its poses."""
__version__ = "0.1.0"
