"""Sky view from one site (`leonav sky`): visible satellites per epoch (view.py) and sky.png (plot.py)."""
