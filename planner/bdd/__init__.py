"""Binary decision diagrams over a model (CUDD through `dd`): the symbolic model, the
supervisor synthesised from the specifications, sifting, readable guards and saved BDDs."""
