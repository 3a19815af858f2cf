//! JSON files the user or another tool writes (`rig.json`, `truth.json`): parsed with the
//! dotted key of any error and a one-line message, so the caller only adds its checks.

use serde::de::DeserializeOwned;

use crate::{Error, ErrorKind};

/// Parses JSON text into `T`; a syntax error is a format error, a wrong or missing field a
/// value error, each naming the key where serde stopped. Anything but white space after the
/// value is refused: a file holds one value.
pub fn decode<T: DeserializeOwned>(text: &str) -> Result<T, Error> {
    let de = &mut serde_json::Deserializer::from_str(text);
    let value = decode_from(de)?;
    de.end().map_err(|e| {
        let msg = e.to_string();
        let msg = msg.split(" at line").next().unwrap_or(&msg).to_string();
        Error::new(ErrorKind::Format, "", format!("expected one JSON value and nothing after it: {msg}")).with_source(e)
    })?;
    Ok(value)
}

fn decode_from<T: DeserializeOwned>(
    de: &mut serde_json::Deserializer<serde_json::de::StrRead<'_>>,
) -> Result<T, Error> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn anything_after_the_value_is_refused() {
        assert_eq!(decode::<Vec<u8>>(" [1, 2] \n").unwrap(), vec![1, 2]);
        for text in ["[1, 2] [3]", "[1, 2]x", "{\"a\": 1}}"] {
            let e = decode::<serde_json::Value>(text).unwrap_err();
            assert_eq!(e.kind(), ErrorKind::Format, "{text}: {e}");
            assert!(e.to_string().contains("nothing after it"), "{text}: {e}");
        }
    }
}
