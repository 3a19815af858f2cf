//! The sensor placement x = (r, alpha, baseline, vergence) plus azimuth, as the user
//! writes it: in the cell file's `[placement]` table or as `r=605,alpha=32,...` on the
//! command line. The geometry it implies lives with the simulator.

use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;

use crate::Error;

/// Toe-in of each camera: a number of degrees, or `"auto"` (axes meet at W's origin).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Vergence {
    /// Each camera turned inward by this many degrees.
    Degrees(f64),
    /// Each camera turned inward so the optical axes meet at the world origin.
    Auto,
}

impl Vergence {
    /// The toe-in in degrees for a rig at distance `r_mm` with `baseline_mm`.
    pub fn degrees(self, r_mm: f64, baseline_mm: f64) -> f64 {
        match self {
            Vergence::Degrees(d) => d,
            Vergence::Auto => (0.5 * baseline_mm / r_mm).atan().to_degrees(),
        }
    }
}

impl fmt::Display for Vergence {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Vergence::Degrees(d) => write!(f, "{d}"),
            Vergence::Auto => f.write_str("auto"),
        }
    }
}

impl Serialize for Vergence {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Vergence::Degrees(d) => s.serialize_f64(*d),
            Vergence::Auto => s.serialize_str("auto"),
        }
    }
}

impl<'de> Deserialize<'de> for Vergence {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Number(f64),
            Text(String),
        }
        match Raw::deserialize(d).map_err(|_| serde::de::Error::custom("expected a number of degrees or \"auto\""))? {
            Raw::Number(v) => Ok(Vergence::Degrees(v)),
            Raw::Text(t) if t == "auto" => Ok(Vergence::Auto),
            Raw::Text(t) => {
                Err(serde::de::Error::custom(format!("expected a number of degrees or \"auto\", got \"{t}\"")))
            }
        }
    }
}

/// Where the rig sits: see docs/design/units-and-frames.md.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Placement {
    /// Distance from the world origin to the rig origin, mm.
    pub r: f64,
    /// Polar angle of the rig origin from the world z axis, deg.
    pub alpha: f64,
    /// Distance between the camera centres, mm.
    pub baseline: f64,
    /// Toe-in per camera.
    pub vergence: Vergence,
    /// Azimuth of the rig's vertical plane from world x, deg.
    pub azimuth: f64,
}

/// The largest distance (r, baseline) a placement may give, mm: 100 m.
pub const MAX_DISTANCE_MM: f64 = 100_000.0;

/// One parameter of a placement, by its name in the paper (and in files and flags).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PlacementParam {
    /// Distance of the rig origin from the world origin, mm.
    R,
    /// Polar angle from the world z axis, deg.
    Alpha,
    /// Distance between the camera centres, mm.
    Baseline,
    /// Toe-in per camera, deg.
    Vergence,
    /// Azimuth of the rig's vertical plane from world x, deg.
    Azimuth,
}

impl PlacementParam {
    /// Every parameter, in the order placements are written.
    pub const ALL: [PlacementParam; 5] = [
        PlacementParam::R,
        PlacementParam::Alpha,
        PlacementParam::Baseline,
        PlacementParam::Vergence,
        PlacementParam::Azimuth,
    ];

    /// The four parameters the study varies (the paper's x).
    pub const STUDIED: [PlacementParam; 4] =
        [PlacementParam::R, PlacementParam::Alpha, PlacementParam::Baseline, PlacementParam::Vergence];

    /// Its name: `r`, `alpha`, `baseline`, `vergence`, `azimuth`.
    pub fn name(self) -> &'static str {
        match self {
            PlacementParam::R => "r",
            PlacementParam::Alpha => "alpha",
            PlacementParam::Baseline => "baseline",
            PlacementParam::Vergence => "vergence",
            PlacementParam::Azimuth => "azimuth",
        }
    }

    /// Every parameter's name, as an error lists them: `r, alpha, baseline, vergence, azimuth`.
    pub fn names() -> String {
        PlacementParam::ALL.map(PlacementParam::name).join(", ")
    }

    /// Its position in [`PlacementParam::ALL`] (and in every array of offsets ordered so).
    pub fn index(self) -> usize {
        self as usize
    }

    /// The parameter called `name`, if any.
    pub fn from_name(name: &str) -> Option<PlacementParam> {
        PlacementParam::ALL.into_iter().find(|p| p.name() == name)
    }

    /// `mm` or `deg`.
    pub fn unit(self) -> &'static str {
        match self {
            PlacementParam::R | PlacementParam::Baseline => "mm",
            _ => "deg",
        }
    }

    /// The name and unit as a plot's axis is labelled: `r, mm`.
    pub fn label(self) -> String {
        format!("{}, {}", self.name(), self.unit())
    }

    /// The study's default search box: the paper's grid for r (400–900 mm) and alpha
    /// (0–60°), ranges around its optimum for baseline (40–200 mm) and vergence (0–10°);
    /// none for the azimuth, which the study does not search.
    pub fn bounds(self) -> Option<(f64, f64)> {
        match self {
            PlacementParam::R => Some((400.0, 900.0)),
            PlacementParam::Alpha => Some((0.0, 60.0)),
            PlacementParam::Baseline => Some((40.0, 200.0)),
            PlacementParam::Vergence => Some((0.0, 10.0)),
            PlacementParam::Azimuth => None,
        }
    }

    /// The step a searched value is written to: 0.1 mm or 0.01°.
    pub fn step(self) -> f64 {
        if self.unit() == "mm" {
            0.1
        } else {
            0.01
        }
    }

    /// The decimals of its step: 1 (0.1 mm) or 2 (0.01°).
    pub fn decimals(self) -> usize {
        if self.unit() == "mm" {
            1
        } else {
            2
        }
    }

    /// Its value in `p` (vergence resolved to degrees).
    pub fn get(self, p: &Placement) -> f64 {
        match self {
            PlacementParam::R => p.r,
            PlacementParam::Alpha => p.alpha,
            PlacementParam::Baseline => p.baseline,
            PlacementParam::Vergence => p.vergence.degrees(p.r, p.baseline),
            PlacementParam::Azimuth => p.azimuth,
        }
    }

    /// `p` with this parameter set to `value` (a vergence in degrees).
    pub fn set(self, p: &Placement, value: f64) -> Placement {
        let mut p = *p;
        match self {
            PlacementParam::R => p.r = value,
            PlacementParam::Alpha => p.alpha = value,
            PlacementParam::Baseline => p.baseline = value,
            PlacementParam::Vergence => p.vergence = Vergence::Degrees(value),
            PlacementParam::Azimuth => p.azimuth = value,
        }
        p
    }
}

impl fmt::Display for PlacementParam {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for PlacementParam {
    type Err = String;

    /// A name; the error lists the names.
    fn from_str(s: &str) -> Result<PlacementParam, String> {
        PlacementParam::from_name(s)
            .ok_or_else(|| format!("unknown parameter, expected one of {}", PlacementParam::names()))
    }
}

impl Placement {
    /// Every parameter to its step, the vergence in degrees, as a drawing would give it:
    /// `r=605.0,alpha=32.00,baseline=81.0,vergence=3.50,azimuth=0.00`.
    pub fn to_step_text(&self) -> String {
        let value = |p: PlacementParam| format!("{}={:.*}", p.name(), p.decimals(), p.get(self));
        PlacementParam::ALL.map(value).join(",")
    }

    /// Checks ranges; `key` prefixes the key named in an error.
    pub fn validate(&self, key: &str) -> Result<(), Error> {
        let k = |name: &str| if key.is_empty() { name.to_string() } else { format!("{key}.{name}") };
        if !(self.r.is_finite() && self.r > 0.0) {
            return Err(Error::value(
                k(PlacementParam::R.name()),
                format!("expected a positive distance in mm, got {}", self.r),
            ));
        }
        if !(self.alpha.is_finite() && (0.0..90.0).contains(&self.alpha)) {
            return Err(Error::value(
                k(PlacementParam::Alpha.name()),
                format!("expected a polar angle in [0, 90) degrees, got {}", self.alpha),
            ));
        }
        if !(self.baseline.is_finite() && self.baseline > 0.0) {
            return Err(Error::value(
                k(PlacementParam::Baseline.name()),
                format!("expected a positive baseline in mm, got {}", self.baseline),
            ));
        }
        if self.r > MAX_DISTANCE_MM {
            return Err(Error::value(
                k(PlacementParam::R.name()),
                format!("expected at most {MAX_DISTANCE_MM} mm, got {}", self.r),
            ));
        }
        if self.baseline > MAX_DISTANCE_MM {
            return Err(Error::value(
                k(PlacementParam::Baseline.name()),
                format!("expected at most {MAX_DISTANCE_MM} mm, got {}", self.baseline),
            ));
        }
        match self.vergence {
            Vergence::Degrees(v) => {
                if !(v.is_finite() && (-45.0..45.0).contains(&v)) {
                    return Err(Error::value(
                        k(PlacementParam::Vergence.name()),
                        format!("expected a toe-in in (-45, 45) degrees or \"auto\", got {v}"),
                    ));
                }
            }
            Vergence::Auto => {
                // "auto" obeys the same range as a number: a rig closer than half its
                // baseline would turn its cameras more than 45 degrees inward.
                let v = self.vergence.degrees(self.r, self.baseline);
                if v.is_nan() || v >= 45.0 {
                    return Err(Error::value(
                        k(PlacementParam::Vergence.name()),
                        format!(
                            "\"auto\" gives a toe-in of {v:.1} degrees at r {} mm and baseline {} mm; expected under 45 (r larger than half the baseline)",
                            self.r, self.baseline
                        ),
                    ));
                }
            }
        }
        if !(self.azimuth.is_finite() && (-360.0..=360.0).contains(&self.azimuth)) {
            return Err(Error::value(
                k(PlacementParam::Azimuth.name()),
                format!("expected an azimuth from -360 to 360 degrees, got {}", self.azimuth),
            ));
        }
        Ok(())
    }

    /// Reads `r=605,alpha=32,baseline=81,vergence=3.5` (any subset, any order) over `self`.
    /// An empty field (`r=605,,alpha=32`, a trailing comma, `r=`) and a parameter given twice
    /// are refused: either would leave unsaid which value was meant.
    pub fn with_overrides(&self, text: &str) -> Result<Placement, Error> {
        let mut p = *self;
        let mut seen: Vec<&str> = Vec::new();
        for part in text.split(',').map(str::trim) {
            if part.is_empty() {
                return Err(Error::value(
                    "placement",
                    format!(
                        "expected name=value fields separated by single commas, found an empty field in \"{text}\""
                    ),
                ));
            }
            let (name, value) = part
                .split_once('=')
                .ok_or_else(|| Error::value("placement", format!("expected name=value, got \"{part}\"")))?;
            let name = name.trim();
            let value = value.trim();
            if name.is_empty() || value.is_empty() {
                let key = if name.is_empty() { "placement".to_string() } else { format!("placement.{name}") };
                return Err(Error::value(key, format!("expected name=value with both given, got \"{part}\"")));
            }
            if seen.contains(&name) {
                return Err(Error::value(
                    format!("placement.{name}"),
                    format!("given twice in \"{text}\"; give each parameter once"),
                ));
            }
            seen.push(name);
            let number = || {
                value.parse::<f64>().map_err(|e| {
                    Error::value(format!("placement.{name}"), format!("expected a number, got \"{value}\""))
                        .with_source(e)
                })
            };
            let param: PlacementParam =
                name.parse().map_err(|what: String| Error::value(format!("placement.{name}"), what))?;
            p = match param {
                PlacementParam::Vergence if value == "auto" => Placement { vergence: Vergence::Auto, ..p },
                _ => param.set(&p, number()?),
            };
        }
        p.validate("placement")?;
        Ok(p)
    }
}

impl fmt::Display for Placement {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "r={},alpha={},baseline={},vergence={}", self.r, self.alpha, self.baseline, self.vergence)?;
        if self.azimuth != 0.0 {
            write!(f, ",azimuth={}", self.azimuth)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn base() -> Placement {
        Placement { r: 605.0, alpha: 32.0, baseline: 120.0, vergence: Vergence::Auto, azimuth: 0.0 }
    }

    #[test]
    fn overrides_parse_and_round_trip() {
        let p = base().with_overrides("r=700, vergence=3.5,baseline=81").unwrap();
        assert_eq!(p.r, 700.0);
        assert_eq!(p.baseline, 81.0);
        assert_eq!(p.vergence, Vergence::Degrees(3.5));
        assert_eq!(base().with_overrides(&p.to_string()).unwrap(), p);
    }

    #[test]
    fn bad_overrides_name_the_key() {
        let e = base().with_overrides("r=-3").unwrap_err();
        assert_eq!(e.key(), "placement.r");
        let e = base().with_overrides("alpha=90").unwrap_err();
        assert_eq!(e.key(), "placement.alpha");
        let e = base().with_overrides("height=3").unwrap_err();
        assert_eq!(e.key(), "placement.height");
        let e = base().with_overrides("vergence=left").unwrap_err();
        assert_eq!(e.key(), "placement.vergence");
    }

    #[test]
    fn a_parameter_twice_or_an_empty_field_is_refused() {
        for (text, key) in [
            ("r=605,r=700", "placement.r"),
            ("r=605,alpha=30,alpha=30", "placement.alpha"),
            ("r=605,,alpha=30", "placement"),
            ("r=605,", "placement"),
            (",r=605", "placement"),
            ("", "placement"),
            ("r=", "placement.r"),
            ("=605", "placement"),
        ] {
            let e = base().with_overrides(text).unwrap_err();
            assert_eq!(e.key(), key, "{text:?}: {e}");
        }
        assert!(base().with_overrides(" r = 605 , alpha=30 ").is_ok());
    }

    #[test]
    fn auto_vergence_and_sizes_obey_the_same_ranges() {
        let e = base().with_overrides("vergence=auto,r=1e-6").unwrap_err();
        assert_eq!(e.key(), "placement.vergence", "{e}");
        assert!(e.to_string().contains("auto"), "{e}");
        assert!(base().with_overrides("vergence=auto,r=605,baseline=81").is_ok());
        assert_eq!(base().with_overrides("r=1e12").unwrap_err().key(), "placement.r");
        assert_eq!(base().with_overrides("baseline=1e12").unwrap_err().key(), "placement.baseline");
    }

    #[test]
    fn each_parameter_sets_what_it_gets_and_parses_its_name() {
        for (i, param) in PlacementParam::ALL.into_iter().enumerate() {
            assert_eq!(param.index(), i, "{param}");
            assert!((param.step() - 10f64.powi(-(param.decimals() as i32))).abs() < 1e-12, "{param}");
            let value = param.get(&base()) + 1.5;
            let p = param.set(&base(), value);
            assert_eq!(param.get(&p), value, "{param}");
            // Only that field changed.
            for other in PlacementParam::ALL.into_iter().filter(|&o| o != param && o != PlacementParam::Vergence) {
                assert_eq!(other.get(&p), other.get(&base()), "{param} moved {other}");
            }
            assert_eq!(param.name().parse::<PlacementParam>(), Ok(param));
            assert_eq!(base().with_overrides(&format!("{param}={value}")).unwrap(), p);
            assert_eq!(serde_json::to_string(&param).unwrap(), format!("\"{param}\""));
        }
        assert!("height".parse::<PlacementParam>().unwrap_err().contains("r, alpha, baseline, vergence, azimuth"));
        let p = Placement { vergence: Vergence::Auto, azimuth: -12.5, ..base() };
        assert_eq!(
            p.to_step_text(),
            format!(
                "r={:.1},alpha={:.2},baseline={:.1},vergence={:.2},azimuth=-12.50",
                p.r,
                p.alpha,
                p.baseline,
                p.vergence.degrees(p.r, p.baseline)
            )
        );
    }

    #[test]
    fn auto_vergence_meets_at_origin() {
        let v = Vergence::Auto.degrees(600.0, 120.0);
        assert!((v.to_radians().tan() - 60.0 / 600.0).abs() < 1e-12);
    }
}
