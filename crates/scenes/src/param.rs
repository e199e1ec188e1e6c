//! Numbers in a scenario that are either fixed or drawn per episode from a range.

use rand::Rng;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::{Deserialize, Serialize, Serializer};
use std::fmt;

/// A scalar that is fixed (`0.45`) or sampled uniformly per episode (`(0.42, 0.48)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Param {
    /// Always this value.
    Fixed(f64),
    /// Uniform in `[lo, hi]`.
    Uniform(f64, f64),
}

impl Param {
    /// A value for one episode.
    pub fn sample(&self, rng: &mut impl Rng) -> f64 {
        match *self {
            Param::Fixed(v) => v,
            Param::Uniform(lo, hi) if hi > lo => rng.random_range(lo..=hi),
            Param::Uniform(lo, _) => lo,
        }
    }

    /// The middle of the range (the value itself when fixed).
    pub fn nominal(&self) -> f64 {
        match *self {
            Param::Fixed(v) => v,
            Param::Uniform(lo, hi) => 0.5 * (lo + hi),
        }
    }

    /// The smallest value it can take.
    pub fn min(&self) -> f64 {
        match *self {
            Param::Fixed(v) | Param::Uniform(v, _) => v,
        }
    }

    /// The largest value it can take.
    pub fn max(&self) -> f64 {
        match *self {
            Param::Fixed(v) | Param::Uniform(_, v) => v,
        }
    }

    /// True when it varies between episodes.
    pub fn is_random(&self) -> bool {
        matches!(self, Param::Uniform(lo, hi) if hi > lo)
    }
}

impl From<f64> for Param {
    fn from(v: f64) -> Self {
        Param::Fixed(v)
    }
}

impl fmt::Display for Param {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Param::Fixed(v) => write!(f, "{v}"),
            Param::Uniform(lo, hi) => write!(f, "{lo}..{hi}"),
        }
    }
}

impl Serialize for Param {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match *self {
            Param::Fixed(v) => s.serialize_f64(v),
            Param::Uniform(lo, hi) => (lo, hi).serialize(s),
        }
    }
}

impl<'de> Deserialize<'de> for Param {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct ParamVisitor;
        impl<'de> Visitor<'de> for ParamVisitor {
            type Value = Param;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or a range `(low, high)`")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Param, E> {
                finite(v).map(Param::Fixed)
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Param, E> {
                Ok(Param::Fixed(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Param, E> {
                Ok(Param::Fixed(v as f64))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Param, A::Error> {
                let lo: f64 = seq.next_element()?.ok_or_else(|| de::Error::invalid_length(0, &self))?;
                let hi: f64 = seq.next_element()?.ok_or_else(|| de::Error::invalid_length(1, &self))?;
                if seq.next_element::<f64>()?.is_some() {
                    return Err(de::Error::custom("a range has exactly two numbers: `(low, high)`"));
                }
                let (lo, hi) = (finite(lo)?, finite(hi)?);
                if lo > hi {
                    return Err(de::Error::custom(format!("range `({lo}, {hi})` has its low end above its high end")));
                }
                Ok(Param::Uniform(lo, hi))
            }
        }
        d.deserialize_any(ParamVisitor)
    }
}

fn finite<E: de::Error>(v: f64) -> Result<f64, E> {
    if v.is_finite() { Ok(v) } else { Err(E::custom(format!("{v} is not a finite number"))) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn parses_numbers_and_ranges() {
        assert_eq!(ron::from_str::<Param>("0.5").unwrap(), Param::Fixed(0.5));
        assert_eq!(ron::from_str::<Param>("2").unwrap(), Param::Fixed(2.0));
        assert_eq!(ron::from_str::<Param>("(1.0, 2)").unwrap(), Param::Uniform(1.0, 2.0));
        let err = ron::from_str::<Param>("(2.0, 1.0)").unwrap_err();
        assert!(err.to_string().contains("low end above its high end"), "{err}");
        assert!(ron::from_str::<Param>("(1.0, 2.0, 3.0)").is_err());
    }

    #[test]
    fn samples_stay_in_range() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let p = Param::Uniform(-1.0, 3.0);
        for _ in 0..1000 {
            let v = p.sample(&mut rng);
            assert!((-1.0..=3.0).contains(&v));
        }
        assert_eq!(Param::Fixed(4.0).sample(&mut rng), 4.0);
        let text = ron::to_string(&p).unwrap();
        assert_eq!(ron::from_str::<Param>(&text).unwrap(), p);
    }
}
