//! Quantities with units, as the papers write them: `"1.4 mm"`, `"937 kg/m^3"`,
//! `"2.49 kg/h"`, `"2.3 l/min"`, `"0.0673 cP"`, `"1013.25 hPa"`, `"5e-6 s"`.
//!
//! A scene field declares its dimension through the marker type of [`Q`]; a bare number is
//! taken as SI, a string must carry a unit of that dimension. Anything else (a unit of the
//! wrong dimension, NaN, infinity, an unknown unit) is an error naming the expected units.

use serde::de::{self, Deserializer, Visitor};
use serde::Deserialize;
use std::fmt;
use std::marker::PhantomData;

use crate::Real;

/// A physical dimension: a name for messages and the units accepted, with SI factors.
pub trait Dimension {
    /// Human name, e.g. "length".
    const NAME: &'static str;
    /// (unit spelling, factor to SI). Spellings are compared after removing spaces and
    /// treating `·` and `*` alike.
    const UNITS: &'static [(&'static str, Real)];
}

macro_rules! dimension {
    ($name:ident, $human:literal, [$(($u:literal, $f:expr)),* $(,)?]) => {
        #[doc = concat!("Dimension marker: ", $human, ".")]
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub struct $name;
        impl Dimension for $name {
            const NAME: &'static str = $human;
            const UNITS: &'static [(&'static str, Real)] = &[$(($u, $f)),*];
        }
    };
}

dimension!(
    Length,
    "length",
    [
        ("m", 1.0),
        ("cm", 1e-2),
        ("mm", 1e-3),
        ("um", 1e-6),
        ("µm", 1e-6)
    ]
);
dimension!(
    Time,
    "time",
    [
        ("s", 1.0),
        ("ms", 1e-3),
        ("us", 1e-6),
        ("µs", 1e-6),
        ("min", 60.0),
        ("h", 3600.0)
    ]
);
dimension!(
    Density,
    "mass density",
    [
        ("kg/m^3", 1.0),
        ("kg/m3", 1.0),
        ("kg/m³", 1.0),
        ("g/cm^3", 1e3),
        ("g/cm3", 1e3),
        ("g/cm³", 1e3)
    ]
);
dimension!(
    MassFlow,
    "mass flow",
    [
        ("kg/s", 1.0),
        ("kg/h", 1.0 / 3600.0),
        ("g/s", 1e-3),
        ("g/min", 1e-3 / 60.0),
        ("kg/min", 1.0 / 60.0)
    ]
);
dimension!(
    Rate,
    "rate (per time)",
    [
        ("1/s", 1.0),
        ("particles/s", 1.0),
        ("grains/s", 1.0),
        ("Hz", 1.0),
        ("1/min", 1.0 / 60.0)
    ]
);
dimension!(
    Velocity,
    "velocity",
    [("m/s", 1.0), ("cm/s", 1e-2), ("mm/s", 1e-3)]
);
dimension!(
    Acceleration,
    "acceleration",
    [("m/s^2", 1.0), ("m/s2", 1.0), ("m/s²", 1.0), ("g", 9.80665)]
);
dimension!(
    Pressure,
    "pressure or elastic modulus",
    [
        ("Pa", 1.0),
        ("hPa", 1e2),
        ("kPa", 1e3),
        ("MPa", 1e6),
        ("GPa", 1e9),
        ("bar", 1e5),
        ("mbar", 1e2),
        ("atm", 101_325.0)
    ]
);
dimension!(
    Viscosity,
    "dynamic viscosity",
    [
        ("Pa*s", 1.0),
        ("Pas", 1.0),
        ("mPa*s", 1e-3),
        ("cP", 1e-3),
        ("P", 0.1)
    ]
);
dimension!(
    VolumeFlow,
    "volume flow",
    [
        ("m^3/s", 1.0),
        ("m3/s", 1.0),
        ("m³/s", 1.0),
        ("l/min", 1e-3 / 60.0),
        ("L/min", 1e-3 / 60.0),
        ("l/s", 1e-3),
        ("L/s", 1e-3)
    ]
);
dimension!(Stiffness, "stiffness", [("N/m", 1.0), ("kN/m", 1e3)]);
dimension!(
    Damping,
    "damping coefficient",
    [("kg/s", 1.0), ("N*s/m", 1.0), ("Ns/m", 1.0)]
);

/// Parse `text` as a quantity of dimension `D`, returning its SI value.
pub fn parse_quantity<D: Dimension>(text: &str) -> Result<Real, String> {
    let t = text.trim();
    let lower = t.trim_start_matches(['+', '-']).to_ascii_lowercase();
    if lower.starts_with("nan") || lower.starts_with("inf") {
        return Err(format!("`{text}` is not a finite number"));
    }
    let split = t
        .char_indices()
        .find(|&(i, c)| {
            !(c.is_ascii_digit()
                || c == '.'
                || c == '+'
                || c == '-'
                || ((c == 'e' || c == 'E')
                    && t[i + 1..]
                        .chars()
                        .next()
                        .is_some_and(|n| n.is_ascii_digit() || n == '-' || n == '+')))
        })
        .map(|(i, _)| i)
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let value: Real = num
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a number followed by a {} unit", D::NAME))?;
    if !value.is_finite() {
        return Err(format!("`{text}` is not a finite number"));
    }
    let unit_norm: String = unit
        .chars()
        .filter(|c| !c.is_whitespace())
        .map(|c| if c == '·' { '*' } else { c })
        .collect();
    if unit_norm.is_empty() {
        return Ok(value);
    }
    let norm = |u: &str| -> String { u.chars().filter(|c| *c != '*').collect() };
    let wanted = norm(&unit_norm);
    for (u, f) in D::UNITS {
        if norm(u) == wanted {
            return Ok(value * f);
        }
    }
    let accepted: Vec<&str> = D::UNITS.iter().map(|(u, _)| *u).collect();
    Err(format!(
        "unit `{}` is not a unit of {} (accepted: {}, or a bare number in SI)",
        unit.trim(),
        D::NAME,
        accepted.join(", ")
    ))
}

/// A scene quantity of dimension `D`, stored in SI.
#[derive(Clone, Copy, PartialEq)]
pub struct Q<D> {
    /// Value in SI units.
    pub si: Real,
    _d: PhantomData<D>,
}

impl<D> Q<D> {
    /// A quantity from its SI value.
    pub const fn si(si: Real) -> Self {
        Self {
            si,
            _d: PhantomData,
        }
    }
}

impl<D: Dimension> fmt::Debug for Q<D> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (SI, {})", self.si, D::NAME)
    }
}

impl<'de, D: Dimension> Deserialize<'de> for Q<D> {
    fn deserialize<De: Deserializer<'de>>(deserializer: De) -> Result<Self, De::Error> {
        struct V<D>(PhantomData<D>);
        impl<D: Dimension> Visitor<'_> for V<D> {
            type Value = Q<D>;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "a {} as an SI number or a string with a unit", D::NAME)
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Q<D>, E> {
                if v.is_finite() {
                    Ok(Q::si(v))
                } else {
                    Err(E::custom(format!("{v} is not a finite number")))
                }
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Q<D>, E> {
                Ok(Q::si(v as Real))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Q<D>, E> {
                Ok(Q::si(v as Real))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<Q<D>, E> {
                parse_quantity::<D>(v).map(Q::si).map_err(E::custom)
            }
        }
        deserializer.deserialize_any(V(PhantomData))
    }
}

/// A plain number that must be finite (NaN and infinity are refused at parse time).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Finite(pub Real);

impl<'de> Deserialize<'de> for Finite {
    fn deserialize<De: Deserializer<'de>>(deserializer: De) -> Result<Self, De::Error> {
        let v = f64::deserialize(deserializer)?;
        if v.is_finite() {
            Ok(Finite(v))
        } else {
            Err(de::Error::custom(format!("{v} is not a finite number")))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_spellings_convert_to_si() {
        let close = |a: Real, b: Real| (a - b).abs() <= 1e-12 * b.abs();
        assert!(close(parse_quantity::<Length>("1.4 mm").unwrap(), 1.4e-3));
        assert!(close(
            parse_quantity::<Density>("937 kg/m^3").unwrap(),
            937.0
        ));
        assert!(close(
            parse_quantity::<MassFlow>("2.49 kg/h").unwrap(),
            2.49 / 3600.0
        ));
        assert!(close(
            parse_quantity::<VolumeFlow>("2.3 l/min").unwrap(),
            2.3e-3 / 60.0
        ));
        assert!(close(
            parse_quantity::<Viscosity>("0.0673 cP").unwrap(),
            6.73e-5
        ));
        assert!(close(
            parse_quantity::<Pressure>("1013.25 hPa").unwrap(),
            101_325.0
        ));
        assert!(close(parse_quantity::<Time>("5e-6 s").unwrap(), 5e-6));
        assert!(close(
            parse_quantity::<Viscosity>("1.8e-5 Pa·s").unwrap(),
            1.8e-5
        ));
        assert!(close(parse_quantity::<Length>("3.5mm").unwrap(), 3.5e-3));
        assert!(close(parse_quantity::<Length>("0.525").unwrap(), 0.525));
    }

    #[test]
    fn wrong_dimension_and_garbage_are_refused_with_reason() {
        let e = parse_quantity::<Length>("937 kg/m^3").unwrap_err();
        assert!(e.contains("not a unit of length"), "{e}");
        assert!(parse_quantity::<Length>("abc mm").is_err());
        assert!(parse_quantity::<Length>("NaN mm").is_err());
        assert!(parse_quantity::<Length>("inf mm").is_err());
    }
}
