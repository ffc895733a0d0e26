//! The enumerated options of the command line as clap values, so that `--help` lists them and
//! a wrong word is refused by name. The spellings are the library's own (the same words
//! `subject.toml` and `suite.toml` use), taken from each type's name or parser, not repeated.

use crate::anatomy::Side;
use crate::skin::pipeline::FitResolution;
use crate::synth::procedural::Sex;
use crate::synth::{Body, Posture, Preset};
use clap::builder::PossibleValue;
use clap::ValueEnum;

impl ValueEnum for Preset {
    fn value_variants<'a>() -> &'a [Self] {
        &Preset::ALL
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        let help = match self {
            Preset::Typical => {
                "0.2 mm noise, plate and skin-marker artefacts, 3 % gaps, full ranges of motion"
            }
            Preset::SmallRom => "as typical with half the ranges of motion",
            Preset::Noisy => "double every error of typical (the drift excepted)",
            Preset::Clean => "no error at all (for exactness checks)",
        };
        Some(PossibleValue::new(self.name()).help(help))
    }
}

impl ValueEnum for Side {
    fn value_variants<'a>() -> &'a [Self] {
        &[Side::Right, Side::Left]
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.as_str()))
    }
}

impl ValueEnum for Posture {
    fn value_variants<'a>() -> &'a [Self] {
        &[Posture::Template, Posture::Varied]
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(match self {
            Posture::Template => PossibleValue::new("template").help("the template's own"),
            Posture::Varied => PossibleValue::new("varied")
                .help("fingers spread, flexed and the thumb moved as seated subjects differ"),
        })
    }
}

impl ValueEnum for Body {
    fn value_variants<'a>() -> &'a [Self] {
        &Body::ALL
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        let help = match self {
            Body::Template => "the template deformed by its own skeleton (always reachable)",
            Body::Procedural => "an anatomical hand independent of the template",
        };
        Some(PossibleValue::new(self.name()).help(help))
    }
}

impl ValueEnum for Sex {
    fn value_variants<'a>() -> &'a [Self] {
        &[Sex::Female, Sex::Male]
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(match self {
            Sex::Female => PossibleValue::new("female"),
            Sex::Male => PossibleValue::new("male"),
        })
    }
}

impl ValueEnum for FitResolution {
    fn value_variants<'a>() -> &'a [Self] {
        &[FitResolution::Low, FitResolution::Full]
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(match self {
            FitResolution::Low => PossibleValue::new("low")
                .help("the ~1,000-face QEM mesh, then transferred (the paper's way)"),
            FitResolution::Full => {
                PossibleValue::new("full").help("the 37,024-face template directly")
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every value the command line offers is the word the library's own parser (used for
    /// `subject.toml` and `suite.toml`) reads as the same value.
    fn round_trips<T: ValueEnum + PartialEq + std::fmt::Debug>(parse: impl Fn(&str) -> Option<T>) {
        for v in T::value_variants() {
            let name = v.to_possible_value().unwrap().get_name().to_string();
            assert_eq!(parse(&name).as_ref(), Some(v), "{name}");
            assert_eq!(T::from_str(&name, false).ok().as_ref(), Some(v), "{name}");
        }
    }

    #[test]
    fn values_are_the_library_spellings() {
        round_trips::<Preset>(|s| s.parse().ok());
        round_trips::<Posture>(|s| s.parse().ok());
        round_trips::<Body>(|s| s.parse().ok());
        round_trips::<FitResolution>(|s| s.parse().ok());
        round_trips::<Side>(|s| {
            toml::from_str::<std::collections::BTreeMap<String, Side>>(&format!("h = \"{s}\""))
                .ok()
                .map(|m| m["h"])
        });
        assert_eq!(Preset::value_variants().len(), Preset::ALL.len());
    }
}
