//! Strict readers for the `loam-core` types whose own serde forms are lenient, and the
//! scene's mixed-type values.
//!
//! Core's [`Transfer`], [`TimeStep`] and [`Wall`] accept (and ignore) unknown keys. A scene
//! file must not, so these readers go through private mirror types that reject them, then
//! convert. [`Transfer`], [`Wall`] and [`LinearSpec`] also accept a short form, the bare name
//! (`"apic"`, `"slip"`, `"lu"`), read as a table holding only the tag key. [`displacement`]
//! reads and writes a constraint's components, each a number or `"free"`.

use crate::schema::LinearSpec;
use loam_core::{TimeStep, Transfer, Wall, WallKind};
use serde::de::value::{MapAccessDeserializer, MapDeserializer};
use serde::de::{self, DeserializeOwned, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
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
    Tpic {},
    Mls {},
}

impl From<TransferTable> for Transfer {
    fn from(t: TransferTable) -> Self {
        match t {
            TransferTable::Pic {} => Transfer::Pic,
            TransferTable::Flip { alpha } => Transfer::Flip { alpha },
            TransferTable::Apic {} => Transfer::Apic,
            TransferTable::Tpic {} => Transfer::Tpic,
            TransferTable::Mls {} => Transfer::Mls,
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

/// `solver.transfer`: `"pic"`, `"apic"`, `"tpic"` or `{ type = "flip", alpha = .. }`.
pub(crate) fn transfer<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Transfer>, D::Error> {
    name_or_table::<D, TransferTable>(d, "type").map(|t| Some(t.into()))
}

/// `solver.time_step`: a table only.
pub(crate) fn time_step<'de, D: Deserializer<'de>>(d: D) -> Result<Option<TimeStep>, D::Error> {
    TimeStepTable::deserialize(d).map(|t| Some(t.into()))
}

/// `solver.linear`: `"lu"` or `{ type = "cg", preconditioner = .. }`.
pub(crate) fn linear<'de, D: Deserializer<'de>>(d: D) -> Result<Option<LinearSpec>, D::Error> {
    name_or_table::<D, LinearSpec>(d, "type").map(Some)
}

/// A constraint's displacement: a list whose items are numbers (`Some`) or `"free"` (`None`).
pub(crate) mod displacement {
    use super::*;

    /// One component: a number or `"free"`.
    struct Component(Option<f64>);

    impl<'de> Deserialize<'de> for Component {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            struct ComponentVisitor;

            impl Visitor<'_> for ComponentVisitor {
                type Value = Component;

                fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                    f.write_str("a number (a displacement, m) or \"free\"")
                }

                fn visit_f64<E: de::Error>(self, x: f64) -> Result<Component, E> {
                    Ok(Component(Some(x)))
                }

                fn visit_i64<E: de::Error>(self, x: i64) -> Result<Component, E> {
                    Ok(Component(Some(x as f64)))
                }

                fn visit_u64<E: de::Error>(self, x: u64) -> Result<Component, E> {
                    Ok(Component(Some(x as f64)))
                }

                fn visit_str<E: de::Error>(self, s: &str) -> Result<Component, E> {
                    if s == "free" {
                        Ok(Component(None))
                    } else {
                        Err(E::invalid_value(de::Unexpected::Str(s), &self))
                    }
                }
            }

            d.deserialize_any(ComponentVisitor)
        }
    }

    impl Serialize for Component {
        fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            match self.0 {
                Some(x) => s.serialize_f64(x),
                None => s.serialize_str("free"),
            }
        }
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Vec<Option<f64>>, D::Error> {
        Vec::<Component>::deserialize(d).map(|v| v.into_iter().map(|c| c.0).collect())
    }

    pub(crate) fn serialize<S: Serializer>(v: &[Option<f64>], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(v.iter().map(|&c| Component(c)))
    }
}

/// An angular velocity: a number (2D, written back as a number) or a list of numbers (3D).
pub(crate) mod angular_velocity {
    use super::*;

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        struct NumberOrList;

        impl<'de> Visitor<'de> for NumberOrList {
            type Value = Vec<f64>;

            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a number (rad/s, in 2D) or a list of three numbers (3D)")
            }

            fn visit_f64<E: de::Error>(self, x: f64) -> Result<Vec<f64>, E> {
                Ok(vec![x])
            }

            fn visit_i64<E: de::Error>(self, x: i64) -> Result<Vec<f64>, E> {
                Ok(vec![x as f64])
            }

            fn visit_u64<E: de::Error>(self, x: u64) -> Result<Vec<f64>, E> {
                Ok(vec![x as f64])
            }

            fn visit_seq<A: de::SeqAccess<'de>>(self, seq: A) -> Result<Vec<f64>, A::Error> {
                Vec::<f64>::deserialize(de::value::SeqAccessDeserializer::new(seq))
            }
        }

        d.deserialize_any(NumberOrList)
    }

    pub(crate) fn serialize<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
        match v {
            [w] => s.serialize_f64(*w),
            v => s.collect_seq(v),
        }
    }
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

    #[derive(Debug, Deserialize, Serialize)]
    #[serde(deny_unknown_fields)]
    struct Doc {
        #[serde(deserialize_with = "transfer")]
        transfer: Option<Transfer>,
        #[serde(default, deserialize_with = "wall")]
        wall: Option<Wall>,
        #[serde(default, deserialize_with = "linear")]
        linear: Option<LinearSpec>,
        #[serde(default, with = "displacement")]
        displacement: Vec<Option<f64>>,
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
    fn linear_solver_short_and_table_forms() {
        use crate::schema::LinearKind;
        use loam_implicit::linear::Preconditioner;
        let doc = read("transfer = \"pic\"\nlinear = \"cholesky\"").unwrap();
        assert_eq!(
            doc.linear,
            Some(LinearSpec {
                kind: LinearKind::Cholesky,
                ..LinearSpec::default()
            })
        );
        let doc =
            read("transfer = \"pic\"\nlinear = { type = \"cg\", preconditioner = \"jacobi\" }");
        let linear = doc.unwrap().linear.unwrap();
        assert_eq!(linear.kind, LinearKind::Cg);
        assert_eq!(linear.preconditioner, Some(Preconditioner::Jacobi));
        let err = read("transfer = \"pic\"\nlinear = { type = \"lu\", tol = 1 }").unwrap_err();
        assert!(err.contains("unknown field `tol`"), "{err}");
    }

    #[test]
    fn displacement_components_are_numbers_or_free() {
        let doc = read("transfer = \"pic\"\ndisplacement = [0.5, \"free\", -2]").unwrap();
        assert_eq!(doc.displacement, vec![Some(0.5), None, Some(-2.0)]);
        let text = toml::to_string(&doc).unwrap();
        assert!(
            text.contains("displacement = [0.5, \"free\", -2.0]"),
            "{text}"
        );
        for bad in ["[\"fixed\"]", "[true]", "[[0.0]]"] {
            let err = read(&format!("transfer = \"pic\"\ndisplacement = {bad}")).unwrap_err();
            assert!(
                err.contains("expected a number (a displacement, m) or \"free\""),
                "{bad}: {err}"
            );
        }
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
