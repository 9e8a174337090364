//! Every unknown key of a file, not only the first: serde stops at the first key a struct
//! does not know (`deny_unknown_fields`), so the loaders remove that key from the parsed
//! document and deserialize it again, until no unknown key is left or another problem
//! shows, and report each key with its path.

use serde_path_to_error::{Path, Segment};

/// The most unknown keys reported from one file (a file of another kind would otherwise
/// have all of its keys listed).
pub const MOST: usize = 50;

/// The key an "unknown field" message of serde names: `sheme` in
/// "unknown field `sheme`, expected one of ...".
pub fn unknown_key(message: &str) -> Option<&str> {
    message.strip_prefix("unknown field `")?.split('`').next()
}

/// A node of a parsed document: a table (key → node), an array (index → node) or a value.
pub trait Node {
    /// The node one path segment below this one: a table's key or an array's index.
    fn child(&mut self, segment: &Segment) -> Option<&mut Self>;

    /// Removes `key` from this node, a table; whether it was there.
    fn remove_key(&mut self, key: &str) -> bool;
}

/// Removes from `root` the unknown `key` that deserializing it failed on at `path` (which
/// ends with the key, or at the table that holds it, for a table read through an internally
/// tagged enum); whether it was found.
pub fn remove<N: Node>(root: &mut N, path: &Path, key: &str) -> bool {
    let segments: Vec<&Segment> = path.iter().collect();
    let parent = match segments.split_last() {
        Some((Segment::Map { key: last }, parent)) if last == key => parent,
        _ => &segments[..],
    };
    let mut node = root;
    for segment in parent {
        match node.child(segment) {
            Some(child) => node = child,
            None => return false,
        }
    }
    node.remove_key(key)
}

impl Node for toml::de::DeValue<'_> {
    fn child(&mut self, segment: &Segment) -> Option<&mut Self> {
        match (self, segment) {
            (Self::Table(t), Segment::Map { key }) => t.get_mut(key.as_str()).map(|v| v.get_mut()),
            (Self::Array(a), Segment::Seq { index }) => a.get_mut(*index).map(|v| v.get_mut()),
            _ => None,
        }
    }

    fn remove_key(&mut self, key: &str) -> bool {
        match self {
            Self::Table(t) => t.remove(key).is_some(),
            _ => false,
        }
    }
}

impl Node for serde_json::Value {
    fn child(&mut self, segment: &Segment) -> Option<&mut Self> {
        match (self, segment) {
            (Self::Object(m), Segment::Map { key }) => m.get_mut(key.as_str()),
            (Self::Array(a), Segment::Seq { index }) => a.get_mut(*index),
            _ => None,
        }
    }

    fn remove_key(&mut self, key: &str) -> bool {
        match self {
            Self::Object(m) => m.remove(key).is_some(),
            _ => false,
        }
    }
}
