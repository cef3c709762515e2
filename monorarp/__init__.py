"""MonoRARP: monocular real-time automotive collision-risk prediction."""
__version__ = "0.1.0"
