//! The TrueType font that host-sim's and liftctl's plots draw their labels with.
//!
//! plotters draws text with its pure-Rust `ab_glyph` renderer, so nothing needs fontconfig or
//! freetype; it only needs the bytes of one font, registered under the family name the plots
//! ask for ([`FAMILY`]). [`register`] finds one: the file an environment variable names,
//! else a sans-serif face among the system's fonts ([`fontdb`] knows where each platform keeps
//! them), preferring DejaVu Sans, which `scripts/deps` installs on Debian.

use fontdb::{Database, Family, Query, Source};
use plotters::style::FontStyle;
use std::path::PathBuf;
use std::sync::OnceLock;

/// The family name every plot asks for.
pub const FAMILY: &str = "sans-serif";

/// Faces tried in order before any other sans-serif face: DejaVu Sans (`fonts-dejavu-core`,
/// what the documented plots were drawn with), then the usual sans-serif faces of other
/// systems.
const PREFERRED: [&str; 4] = ["DejaVu Sans", "Liberation Sans", "Arial", "Helvetica"];

/// Finds a font and registers it with plotters as [`FAMILY`], once per process; returns where
/// it came from. `env_var` names a variable that may hold the path of a font file to use
/// instead (`HOST_SIM_FONT`, `LIFTCTL_FONT`). The first call decides for the whole process;
/// the error says how to get a font.
pub fn register(env_var: &str) -> Result<PathBuf, String> {
    static FOUND: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    FOUND
        .get_or_init(|| {
            let named = std::env::var_os(env_var)
                .map(PathBuf::from)
                .and_then(|p| std::fs::read(&p).ok().map(|b| (p, b)));
            // The named file first; a system face when it is missing or not a font.
            named
                .into_iter()
                .chain(std::iter::once_with(system_font).flatten())
                .find_map(|(path, bytes)| {
                    // plotters keeps a registered font for the life of the program.
                    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                    plotters::style::register_font(FAMILY, FontStyle::Normal, bytes)
                        .ok()
                        .map(|()| path)
                })
                .ok_or_else(|| {
                    format!(
                        "no TrueType font found for the plots: install one (Debian: \
                         fonts-dejavu-core, which scripts/deps installs) or set \
                         {env_var}=/path/to/font.ttf"
                    )
                })
        })
        .clone()
}

/// A regular sans-serif face from the system's font folders: its file and bytes.
fn system_font() -> Option<(PathBuf, Vec<u8>)> {
    let mut db = Database::new();
    db.load_system_fonts();
    let families: Vec<Family<'_>> = PREFERRED
        .iter()
        .map(|&name| Family::Name(name))
        .chain([Family::SansSerif])
        .collect();
    // One query per family, so that a preferred family found only in a collection (a face
    // index other than 0, which ab_glyph does not read) does not hide the next one.
    families.iter().find_map(|family| {
        let id = db.query(&Query {
            families: std::slice::from_ref(family),
            ..Query::default()
        })?;
        match db.face_source(id)? {
            (Source::File(path), 0) => std::fs::read(&path).ok().map(|b| (path, b)),
            (Source::SharedFile(path, data), 0) => Some((path, (*data).as_ref().to_vec())),
            _ => None,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A named file that is no font does not stop the plots: a system face is used instead,
    /// as when the variable names no file (when the machine has no font at all, the error
    /// names the variable).
    #[test]
    fn a_named_file_that_is_no_font_falls_back_to_a_system_face() {
        let not_a_font = std::env::temp_dir().join("liftfw-plotfont-not-a-font.ttf");
        assert!(std::fs::write(&not_a_font, b"not a font").is_ok());
        std::env::set_var("LIFTFW_PLOTFONT_TEST_FONT", &not_a_font);
        match register("LIFTFW_PLOTFONT_TEST_FONT") {
            Ok(path) => assert_ne!(path, not_a_font),
            Err(e) => assert!(e.contains("LIFTFW_PLOTFONT_TEST_FONT="), "{e}"),
        }
    }
}
