//! The file forms of core's option types: strict tables, and a short form.
//!
//! [`Transfer`](crate::Transfer) and [`Wall`](crate::Wall) are written as tables tagged by
//! one key (`{ type = "flip", alpha = 0.95 }`, `{ kind = "slip", separable = true }`) or, in
//! the short form, as the bare tag (`"apic"` reads as `{ type = "apic" }`, `"slip"` as
//! `{ kind = "slip" }`); [`TimeStep`](crate::TimeStep) as a table only. Every table rejects a
//! key it does not know, so a misspelt setting is an error instead of being ignored.
//!
//! Why `Deserialize` is written by hand for `Transfer` and `Wall`: serde's derive cannot give
//! both. An internally tagged enum lets unknown keys through on its unit variants, even with
//! `deny_unknown_fields`, and a derived type reads either a name or a table, not both. So
//! each of them reads its table through a private representation beside it, derived with
//! `deny_unknown_fields` (for `Transfer`, empty struct variants `Apic {}` in place of the
//! unit variants), and [`name_or_table`] adds the short form. `TimeStep` has struct variants
//! only and no short form, so its derive with `deny_unknown_fields` is already strict.
//! `Serialize` stays derived and writes the table form, which reads back to the same value.

use serde::Deserializer;
use serde::de::value::{MapAccessDeserializer, MapDeserializer};
use serde::de::{self, DeserializeOwned, MapAccess, Visitor};
use std::fmt;
use std::marker::PhantomData;

/// Reads `T` from a table, or from a bare string `name` as if it were the one-entry table
/// `{ key = name }` (the short form).
///
/// `T`'s own table form decides what is accepted and how errors read (an unknown key, a
/// missing one, an unknown name); anything other than a string or a table is an error
/// "expected a name or a table with a `key` key".
pub fn name_or_table<'de, D: Deserializer<'de>, T: DeserializeOwned>(
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
    use crate::{TimeStep, Transfer, Wall, WallKind};
    use serde::{Deserialize, Serialize};

    /// A document holding one of each type, as a scene file holds them.
    #[derive(Debug, PartialEq, Deserialize, Serialize)]
    #[serde(deny_unknown_fields)]
    struct Doc {
        #[serde(default)]
        transfer: Option<Transfer>,
        #[serde(default)]
        wall: Option<Wall>,
        #[serde(default)]
        time_step: Option<TimeStep>,
    }

    fn read(text: &str) -> Result<Doc, String> {
        toml::from_str(text).map_err(|e| e.message().to_owned())
    }

    #[test]
    fn short_and_table_forms_read_the_same() {
        for (text, transfer) in [
            ("transfer = \"apic\"", Transfer::Apic),
            ("transfer = { type = \"apic\" }", Transfer::Apic),
            ("transfer = \"tpic\"", Transfer::Tpic),
            ("transfer = \"mls\"", Transfer::Mls),
            ("transfer = \"pic\"", Transfer::Pic),
            (
                "transfer = { type = \"flip\", alpha = 0.9 }",
                Transfer::Flip { alpha: 0.9 },
            ),
        ] {
            assert_eq!(read(text).unwrap().transfer, Some(transfer), "{text}");
        }
        for text in ["wall = \"slip\"", "wall = { kind = \"slip\" }"] {
            assert_eq!(
                read(text).unwrap().wall,
                Some(Wall::new(WallKind::Slip)),
                "{text}"
            );
        }
        let doc = read("wall = { kind = \"no_slip\", separable = true }").unwrap();
        assert_eq!(
            doc.wall,
            Some(Wall {
                kind: WallKind::NoSlip,
                separable: true
            })
        );
        let doc = read("time_step = { type = \"adaptive\", cfl = 0.4, max_dt = 1e-3 }").unwrap();
        assert_eq!(
            doc.time_step,
            Some(TimeStep::Adaptive {
                cfl: 0.4,
                max_dt: 1e-3
            })
        );
    }

    #[test]
    fn unknown_keys_are_rejected() {
        for (text, expected) in [
            (
                "transfer = { type = \"flip\", alpha = 0.9, beta = 1 }",
                "unknown field `beta`, expected `alpha`",
            ),
            (
                "transfer = { type = \"apic\", alpha = 0.9 }",
                "unknown field `alpha`, there are no fields",
            ),
            (
                "wall = { kind = \"slip\", friction = 0.3 }",
                "unknown field `friction`, expected `kind` or `separable`",
            ),
            (
                "time_step = { type = \"fixed\", dt = 1e-4, cfl = 0.5 }",
                "unknown field `cfl`, expected `dt`",
            ),
        ] {
            let err = read(text).unwrap_err();
            assert!(err.contains(expected), "{text}: {err}");
        }
    }

    #[test]
    fn bad_names_and_values_say_what_was_expected() {
        for (text, expected) in [
            (
                "transfer = 3",
                "expected a name or a table with a `type` key",
            ),
            (
                "wall = [\"slip\"]",
                "expected a name or a table with a `kind` key",
            ),
            (
                "transfer = \"sph\"",
                "unknown variant `sph`, expected one of `pic`",
            ),
            (
                "wall = \"sticky\"",
                "unknown variant `sticky`, expected one of `free`",
            ),
            ("transfer = \"flip\"", "missing field `alpha`"),
            (
                "time_step = \"fixed\"",
                "expected internally tagged enum TimeStep",
            ),
        ] {
            let err = read(text).unwrap_err();
            assert!(err.contains(expected), "{text}: {err}");
        }
    }

    #[test]
    fn written_forms_read_back() {
        let transfers = [
            Transfer::Pic,
            Transfer::Flip { alpha: 0.95 },
            Transfer::Apic,
            Transfer::Tpic,
            Transfer::Mls,
        ];
        let walls = [
            Wall::new(WallKind::Free),
            Wall::new(WallKind::Fixed),
            Wall {
                kind: WallKind::Slip,
                separable: true,
            },
            Wall::new(WallKind::NoSlip),
        ];
        let steps = [
            TimeStep::Fixed { dt: 1e-4 },
            TimeStep::Adaptive {
                cfl: 0.4,
                max_dt: 1e-3,
            },
        ];
        for (k, transfer) in transfers.into_iter().enumerate() {
            let doc = Doc {
                transfer: Some(transfer),
                wall: Some(walls[k % walls.len()]),
                time_step: Some(steps[k % steps.len()]),
            };
            let text = toml::to_string(&doc).unwrap();
            assert_eq!(read(&text).unwrap(), doc, "{text}");
            let json = serde_json::to_string(&doc).unwrap();
            assert_eq!(serde_json::from_str::<Doc>(&json).unwrap(), doc, "{json}");
        }
    }
}
