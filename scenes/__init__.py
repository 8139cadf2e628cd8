"""Built-in scenes (TOML). ``warp-cloth scenes`` lists them; ``warp-cloth run NAME`` runs one."""
