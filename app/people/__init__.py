"""People at the station: roles and permissions, passwords, sessions and API tokens, and the
sign-in throttle."""
