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
}
