//! Reading `recommended.json` back (the study report writes it): the recommended placement
//! and method that `placement --study`, `ablate --study` and the commissioning steps take
//! from a study folder, checked on read. The other keys are figures for people and are not
//! read.

use std::path::Path;

use camplace_config::{Placement, Vergence};
use camplace_estimator::Method;

use crate::{Error, Result};

/// What a study recommends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Recommended {
    /// The placement, every parameter given.
    pub placement: Placement,
    /// The sensor method it was measured with.
    pub method: Method,
}

impl Recommended {
    /// Reads `dir/recommended.json` through the bounded text reader (a device or a file past
    /// the text budget is refused before reading).
    pub fn load(dir: &Path) -> Result<Recommended> {
        let path = dir.join("recommended.json");
        let bytes = camplace_config::read_bounded(&path, camplace_config::FileKind::Text)?;
        Self::from_json(&bytes).map_err(|what| Error::Other(format!("{}: {what}", path.display())))
    }

    /// Decodes and checks the bytes of a `recommended.json`; the error names the key.
    pub fn from_json(bytes: &[u8]) -> std::result::Result<Recommended, String> {
        // serde_json refuses anything but white space after the value.
        let v: serde_json::Value = serde_json::from_slice(bytes)
            .map_err(|e| format!("expected the recommended.json a study writes (one JSON object): {e}"))?;
        if !v.is_object() {
            return Err("expected the recommended.json a study writes (one JSON object)".to_string());
        }
        let expected = "placement: expected a placement such as \"r=605,alpha=32,baseline=81,vergence=3.5\"";
        let text = v["placement"].as_str().ok_or_else(|| expected.to_string())?;
        // Every parameter but the azimuth is written out, so the base's values never show
        // through; a study's placements have azimuth 0 unless they say otherwise.
        let base = Placement { r: 0.0, alpha: 0.0, baseline: 0.0, vergence: Vergence::Auto, azimuth: 0.0 };
        let placement = base
            .with_overrides(text)
            .map_err(|e| format!("{expected}: {e}"))
            .and_then(|p| p.validate("placement").map(|()| p).map_err(|e| e.to_string()))?;
        let method = v["method"]
            .as_str()
            .and_then(|m| m.parse::<Method>().ok())
            .ok_or_else(|| "method: expected \"one-shot\" or \"phase-12\"".to_string())?;
        Ok(Recommended { placement, method })
    }

    /// The two keys this reader takes, as JSON (a study's file carries more).
    pub fn to_json(&self) -> String {
        serde_json::json!({ "placement": self.placement.to_string(), "method": self.method.to_string() }).to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_what_it_writes_and_names_the_bad_key() {
        let text = br#"{"placement": "r=605,alpha=32,baseline=81,vergence=3.5", "method": "phase-12", "seed": 1}"#;
        let r = Recommended::from_json(text).unwrap();
        assert_eq!(r.placement.r, 605.0);
        assert_eq!(r.method, Method::Phase12);
        assert_eq!(Recommended::from_json(r.to_json().as_bytes()).unwrap(), r);
        for (bad, key) in [
            (&br#"{"placement": "r=605", "method": "one-shot"}"#[..], "placement"),
            (br#"{"placement": "r=605,alpha=32,baseline=81,vergence=3.5", "method": "two-shot"}"#, "method"),
            (br#"{"placement": "r=605,alpha=32,baseline=81,vergence=3.5", "method": "one-shot"} 7"#, "one JSON object"),
            (br#"[1]"#, "one JSON object"),
        ] {
            let e = Recommended::from_json(bad).unwrap_err();
            assert!(e.contains(key), "{e}");
        }
    }
}
