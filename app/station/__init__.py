"""One station process: the loop that owns the live state, the round it runs, the requests
people send it, and what each round commits and shows (the headless `sp run` loop too)."""
