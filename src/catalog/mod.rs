//! Schema and loader for the instrument catalog in `instruments/*.toml`.
