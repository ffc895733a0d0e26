//! Length units of files; the core is always millimetres.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// The length unit a file's coordinates are written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Units {
    /// Metres (glTF's unit).
    Metres,
    /// Centimetres.
    Centimetres,
    /// Millimetres (the toolkit's unit).
    Millimetres,
    /// Inches (some CAD exports).
    Inches,
}

impl Units {
    /// Millimetres per unit.
    pub fn to_mm(self) -> f64 {
        match self {
            Units::Metres => 1000.0,
            Units::Centimetres => 10.0,
            Units::Millimetres => 1.0,
            Units::Inches => 25.4,
        }
    }

    /// The unit in which a length whose number is `raw` most plausibly measures `expected_mm`
    /// (nearest on a log scale, so a factor of 10 too big and too small weigh the same), to
    /// name in an error when a file's numbers are the wrong size for its declared unit.
    pub fn likely(raw: f64, expected_mm: f64) -> Units {
        [
            Units::Millimetres,
            Units::Centimetres,
            Units::Inches,
            Units::Metres,
        ]
        .into_iter()
        .min_by(|a, b| {
            let off = |u: &Units| (raw * u.to_mm() / expected_mm).ln().abs();
            off(a).total_cmp(&off(b))
        })
        .unwrap_or(Units::Millimetres)
    }
}

impl FromStr for Units {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "m" | "metre" | "metres" | "meter" | "meters" => Ok(Units::Metres),
            "cm" | "centimetre" | "centimetres" | "centimeter" | "centimeters" => {
                Ok(Units::Centimetres)
            }
            "mm" | "millimetre" | "millimetres" | "millimeter" | "millimeters" => {
                Ok(Units::Millimetres)
            }
            "in" | "inch" | "inches" => Ok(Units::Inches),
            other => Err(format!(
                "unknown length unit '{other}' (expected m, cm, mm or in)"
            )),
        }
    }
}

impl fmt::Display for Units {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Units::Metres => "m",
            Units::Centimetres => "cm",
            Units::Millimetres => "mm",
            Units::Inches => "in",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 180 mm hand written in each unit is recognised as that unit, and a borderline value
    /// goes to the unit nearer on a log scale.
    #[test]
    fn likely_unit_recovers_the_unit_of_a_known_length() {
        for u in [
            Units::Metres,
            Units::Centimetres,
            Units::Millimetres,
            Units::Inches,
        ] {
            assert_eq!(Units::likely(180.0 / u.to_mm(), 180.0), u);
        }
        // 180 mm read as 7.1: inches (7.09) rather than cm (18).
        assert_eq!(Units::likely(7.1, 180.0), Units::Inches);
        assert_eq!(Units::likely(0.5, 180.0), Units::Metres);
    }
}
