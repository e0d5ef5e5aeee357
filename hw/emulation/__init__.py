"""The emulated station as a whole: start a device file's emulators (`launch`), the world
behind them that faults and people's maintenance act on (`world`), and the scene they share
(`scene`: where a robot holds the nutrunner down)."""
