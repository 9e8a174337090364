//! The scene's own serde forms: the short form of [`LinearSpec`] and the mixed-type values.
//!
//! [`linear`] reads `solver.linear` as a bare name (`"lu"`) or a table, as core's
//! [`loam_core::serde_form::name_or_table`] does for core's option types (whose own
//! `Deserialize` is strict and takes the short form, so the scene uses them directly).
//! [`displacement`] reads and writes a constraint's components, each a number or `"free"`;
//! [`angular_velocity`] a number (2D) or a list (3D).

use crate::schema::LinearSpec;
use loam_core::serde_form::name_or_table;
use serde::de::{self, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;

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
                    f.write_str("a number (a displacement in m, a force in N) or \"free\"")
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

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize, Serialize)]
    #[serde(deny_unknown_fields)]
    struct Doc {
        #[serde(default, deserialize_with = "linear")]
        linear: Option<LinearSpec>,
        #[serde(default, with = "displacement")]
        displacement: Vec<Option<f64>>,
    }

    fn read(text: &str) -> Result<Doc, String> {
        toml::from_str(text).map_err(|e| e.message().to_owned())
    }

    #[test]
    fn linear_solver_short_and_table_forms() {
        use crate::schema::LinearKind;
        use loam_implicit::linear::Preconditioner;
        let doc = read("linear = \"cholesky\"").unwrap();
        assert_eq!(
            doc.linear,
            Some(LinearSpec {
                kind: LinearKind::Cholesky,
                ..LinearSpec::default()
            })
        );
        let doc = read("linear = { type = \"cg\", preconditioner = \"jacobi\" }");
        let linear = doc.unwrap().linear.unwrap();
        assert_eq!(linear.kind, LinearKind::Cg);
        assert_eq!(linear.preconditioner, Some(Preconditioner::Jacobi));
        let err = read("linear = { type = \"lu\", tol = 1 }").unwrap_err();
        assert!(err.contains("unknown field `tol`"), "{err}");
        let err = read("linear = 3").unwrap_err();
        assert!(err.contains("a name or a table with a `type` key"), "{err}");
    }

    #[test]
    fn displacement_components_are_numbers_or_free() {
        let doc = read("displacement = [0.5, \"free\", -2]").unwrap();
        assert_eq!(doc.displacement, vec![Some(0.5), None, Some(-2.0)]);
        let text = toml::to_string(&doc).unwrap();
        assert!(
            text.contains("displacement = [0.5, \"free\", -2.0]"),
            "{text}"
        );
        for bad in ["[\"fixed\"]", "[true]", "[[0.0]]"] {
            let err = read(&format!("displacement = {bad}")).unwrap_err();
            assert!(
                err.contains("expected a number (a displacement in m, a force in N) or \"free\""),
                "{bad}: {err}"
            );
        }
    }
}
