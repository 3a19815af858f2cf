//! JSON files the user or another tool writes (`rig.json`, `truth.json`): parsed with the
//! dotted key of any error and a one-line message, so the caller only adds its checks.

use serde::de::DeserializeOwned;

use crate::{Error, ErrorKind};

/// Parses JSON text into `T`; a syntax error is a format error, a wrong or missing field a
/// value error, each naming the key where serde stopped.
pub fn decode<T: DeserializeOwned>(text: &str) -> Result<T, Error> {
    let de = &mut serde_json::Deserializer::from_str(text);
    serde_path_to_error::deserialize(de).map_err(|e| {
        let key = e.path().to_string();
        let inner = e.into_inner();
        let kind = if inner.is_syntax() || inner.is_eof() { ErrorKind::Format } else { ErrorKind::Value };
        let key = if key == "." { String::new() } else { key };
        let msg = inner.to_string();
        let msg = msg.split(" at line").next().unwrap_or(&msg).to_string();
        Error::new(kind, key, msg).with_source(inner)
    })
}
