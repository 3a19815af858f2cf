//! Laying one TOML table over another, key by key (a cell over the default, a `[[trays]]`
//! entry over `[tray]`), and serde's messages reworded as one-line "expected ..." errors.

/// Lays `user` over `base`, table by table.
pub(crate) fn merge(base: &mut toml::Table, user: toml::Table) {
    for (key, value) in user {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(u)) => merge(b, u),
            (_, v) => {
                base.insert(key, v);
            }
        }
    }
}

/// Rewords serde's messages into "expected ..." one-liners.
pub(crate) fn explain(inner: &str) -> String {
    if let Some(rest) = inner.strip_prefix("unknown field ") {
        return format!("unknown key {rest}");
    }
    inner.to_string()
}
