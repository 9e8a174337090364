//! The `.pvd` collection file that makes the frames one time series in ParaView.
//!
//! vtkio does not write `.pvd` files, and the format is a few lines of XML, so it is written
//! by hand here.

use super::{OutputError, write_atomically};
use std::path::Path;

/// One frame of a series: its simulated time and its file name relative to the `.pvd`.
#[derive(Clone, Debug, PartialEq)]
pub struct PvdEntry {
    /// Simulated time (s).
    pub time: f64,
    /// File name of the frame, relative to the folder of the `.pvd`.
    pub file: String,
}

/// Writes the collection listing `entries` to `path`, atomically (a reader never sees a
/// half-written file).
pub fn write_pvd(path: &Path, entries: &[PvdEntry]) -> Result<(), OutputError> {
    write_atomically(path, render(entries).as_bytes())
}

/// Reads a collection written by [`write_pvd`] (one `<DataSet timestep=".." file=".."/>`
/// per line); times come back with the bits they were written with (they are written in
/// Rust's shortest round-trip form).
pub fn read_pvd(path: &Path) -> Result<Vec<PvdEntry>, OutputError> {
    let text = std::fs::read_to_string(path).map_err(|source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse(&text).map_err(|(line, message)| OutputError::Series {
        path: path.to_path_buf(),
        line,
        message,
    })
}

/// The entries of a collection, or the 1-based line and what is wrong with it.
fn parse(text: &str) -> Result<Vec<PvdEntry>, (usize, String)> {
    let mut entries = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if !line.trim_start().starts_with("<DataSet") {
            continue;
        }
        let attribute = |name: &str| {
            let key = format!(" {name}=\"");
            let start = line.find(&key)? + key.len();
            let len = line[start..].find('"')?;
            Some(&line[start..start + len])
        };
        let time = attribute("timestep")
            .and_then(|t| t.parse::<f64>().ok())
            .ok_or_else(|| (i + 1, "a DataSet without a numeric `timestep`".to_owned()))?;
        let file = attribute("file")
            .map(unescape)
            .ok_or_else(|| (i + 1, "a DataSet without a `file`".to_owned()))?;
        entries.push(PvdEntry { time, file });
    }
    Ok(entries)
}

/// The inverse of [`escape`].
fn unescape(s: &str) -> String {
    s.replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"")
        .replace("&amp;", "&")
}

fn render(entries: &[PvdEntry]) -> String {
    let mut xml = String::from(
        "<?xml version=\"1.0\"?>\n\
         <VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  \
         <Collection>\n",
    );
    for e in entries {
        xml.push_str(&format!(
            "    <DataSet timestep=\"{}\" group=\"\" part=\"0\" file=\"{}\"/>\n",
            e.time,
            escape(&e.file)
        ));
    }
    xml.push_str("  </Collection>\n</VTKFile>\n");
    xml
}

/// Escapes the characters that may not appear in an XML attribute value.
fn escape(s: &str) -> String {
    s.chars()
        .fold(String::with_capacity(s.len()), |mut out, c| {
            match c {
                '&' => out.push_str("&amp;"),
                '<' => out.push_str("&lt;"),
                '>' => out.push_str("&gt;"),
                '"' => out.push_str("&quot;"),
                c => out.push(c),
            }
            out
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn collection_lists_each_frame_with_its_time() {
        let xml = render(&[
            PvdEntry {
                time: 0.0,
                file: "frame_0000.vtu".into(),
            },
            PvdEntry {
                time: 0.25,
                file: "a&b.vtu".into(),
            },
        ]);
        assert!(
            xml.contains("<DataSet timestep=\"0\" group=\"\" part=\"0\" file=\"frame_0000.vtu\"/>")
        );
        assert!(xml.contains("timestep=\"0.25\" group=\"\" part=\"0\" file=\"a&amp;b.vtu\""));
        assert!(xml.trim_end().ends_with("</VTKFile>"));
    }

    #[test]
    fn collection_reads_back_with_the_same_times_and_names() {
        let entries = vec![
            PvdEntry {
                time: 0.0,
                file: "frame_0000.vtu".into(),
            },
            PvdEntry {
                time: 0.1 + 0.2,
                file: "a&b\"<c>.vtu".into(),
            },
            PvdEntry {
                time: 1.0 / 3.0,
                file: "frame_0002.vtu".into(),
            },
        ];
        let back = parse(&render(&entries)).unwrap();
        assert_eq!(back, entries);
        assert_eq!(back[1].time.to_bits(), (0.1f64 + 0.2).to_bits());
        let err = parse("<Collection>\n  <DataSet timestep=\"x\" file=\"f.vtu\"/>\n").unwrap_err();
        assert_eq!(err.0, 2);
    }
}
