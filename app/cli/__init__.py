"""The `sp` command: `main` parses and dispatches, `station` runs stations (`run`, `serve`,
`emulate`, `audit`), `common` holds what the subcommands share."""
