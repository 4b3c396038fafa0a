//! Measurement campaigns: spec (TOML) -> plan (plain data) -> execute.
