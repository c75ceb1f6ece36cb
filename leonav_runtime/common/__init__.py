"""Small pieces every package shares: errors, output files, TOML reading, UTC parsing, logging,
provenance, figure style, report.html, lazy package exports and the one-line-error parser."""
