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
