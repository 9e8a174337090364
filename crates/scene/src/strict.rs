//! Strict readers for the `loam-core` types whose own serde forms are lenient.
//!
//! Core's [`Transfer`], [`TimeStep`] and [`Wall`] accept (and ignore) unknown keys. A scene
//! file must not, so these readers go through private mirror types that reject them, then
//! convert. [`Transfer`] and [`Wall`] also accept a short form, the bare name (`"apic"`,
//! `"slip"`), read as a table holding only the tag key.

use loam_core::{TimeStep, Transfer, Wall, WallKind};
use serde::de::value::{MapAccessDeserializer, MapDeserializer};
use serde::de::{self, DeserializeOwned, MapAccess, Visitor};
use serde::{Deserialize, Deserializer};
use std::fmt;
use std::marker::PhantomData;

// Empty struct variants, not unit variants: serde lets extra keys through on the unit
// variants of an internally tagged enum, even with `deny_unknown_fields`.
#[derive(Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
enum TransferTable {
    Pic {},
    Flip { alpha: f64 },
    Apic {},
}

impl From<TransferTable> for Transfer {
    fn from(t: TransferTable) -> Self {
        match t {
            TransferTable::Pic {} => Transfer::Pic,
            TransferTable::Flip { alpha } => Transfer::Flip { alpha },
            TransferTable::Apic {} => Transfer::Apic,
        }
    }
}

#[derive(Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
enum TimeStepTable {
    Fixed { dt: f64 },
    Adaptive { cfl: f64, max_dt: f64 },
}

impl From<TimeStepTable> for TimeStep {
    fn from(t: TimeStepTable) -> Self {
        match t {
            TimeStepTable::Fixed { dt } => TimeStep::Fixed { dt },
            TimeStepTable::Adaptive { cfl, max_dt } => TimeStep::Adaptive { cfl, max_dt },
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WallTable {
    kind: WallKind,
    #[serde(default)]
    separable: bool,
}

impl From<WallTable> for Wall {
    fn from(t: WallTable) -> Self {
        Wall {
            kind: t.kind,
            separable: t.separable,
        }
    }
}

/// `solver.transfer`: `"pic"`, `"apic"` or `{ type = "flip", alpha = .. }`.
pub(crate) fn transfer<'de, D: Deserializer<'de>>(d: D) -> Result<Transfer, D::Error> {
    name_or_table::<D, TransferTable>(d, "type").map(Into::into)
}

/// `solver.time_step`: a table only.
pub(crate) fn time_step<'de, D: Deserializer<'de>>(d: D) -> Result<TimeStep, D::Error> {
    TimeStepTable::deserialize(d).map(Into::into)
}

/// A face of `[boundaries]`: `"slip"` or `{ kind = "slip", separable = true }`.
pub(crate) fn wall<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Wall>, D::Error> {
    name_or_table::<D, WallTable>(d, "kind").map(|w| Some(w.into()))
}

/// Reads `T` from a table, or from a bare string `s` as if it were the table `{ key = s }`.
fn name_or_table<'de, D: Deserializer<'de>, T: DeserializeOwned>(
    d: D,
    key: &'static str,
) -> Result<T, D::Error> {
    struct NameOrTable<T> {
        key: &'static str,
        target: PhantomData<T>,
    }

    impl<'de, T: DeserializeOwned> Visitor<'de> for NameOrTable<T> {
        type Value = T;

        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "a name or a table with a `{}` key", self.key)
        }

        fn visit_str<E: de::Error>(self, name: &str) -> Result<T, E> {
            T::deserialize(MapDeserializer::new(std::iter::once((self.key, name))))
        }

        fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<T, A::Error> {
            T::deserialize(MapAccessDeserializer::new(map))
        }
    }

    d.deserialize_any(NameOrTable {
        key,
        target: PhantomData,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Doc {
        #[serde(deserialize_with = "transfer")]
        transfer: Transfer,
        #[serde(default, deserialize_with = "wall")]
        wall: Option<Wall>,
    }

    fn read(text: &str) -> Result<Doc, String> {
        toml::from_str(text).map_err(|e| e.message().to_owned())
    }

    #[test]
    fn short_and_table_forms_read_the_same() {
        for (text, transfer) in [
            ("transfer = \"apic\"", Transfer::Apic),
            ("transfer = { type = \"apic\" }", Transfer::Apic),
            ("transfer = \"pic\"", Transfer::Pic),
            (
                "transfer = { type = \"flip\", alpha = 0.9 }",
                Transfer::Flip { alpha: 0.9 },
            ),
        ] {
            assert_eq!(read(text).unwrap().transfer, transfer, "{text}");
        }
        let doc = read("transfer = \"pic\"\nwall = \"slip\"").unwrap();
        assert_eq!(doc.wall, Some(Wall::new(WallKind::Slip)));
        let doc = read("transfer = \"pic\"\nwall = { kind = \"no_slip\", separable = true }");
        assert_eq!(
            doc.unwrap().wall,
            Some(Wall {
                kind: WallKind::NoSlip,
                separable: true
            })
        );
    }

    #[test]
    fn unknown_keys_are_rejected() {
        for text in [
            "transfer = { type = \"flip\", alpha = 0.9, beta = 1 }",
            "transfer = { type = \"apic\", alpha = 0.9 }",
            "transfer = \"pic\"\nwall = { kind = \"slip\", friction = 0.3 }",
        ] {
            let err = read(text).unwrap_err();
            assert!(err.contains("unknown field"), "{text}: {err}");
        }
        let err = read("transfer = 3").unwrap_err();
        assert!(err.contains("a name or a table with a `type` key"), "{err}");
    }
}
