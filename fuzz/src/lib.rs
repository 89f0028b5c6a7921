//! What every fuzz target asserts of a loader's result: Ok, or an error that names the
//! file and is one line. A panic, an abort (an allocation beyond libFuzzer's
//! `-malloc_limit_mb`), a hang or a failed assertion is a crash for libFuzzer.

use std::path::Path;

/// The value, or `None` after checking that the error names `path` and is one line.
pub fn clean<T>(path: &Path, r: matedit::Result<T>) -> Option<T> {
    match r {
        Ok(v) => Some(v),
        Err(e) => {
            let m = e.to_string();
            assert!(
                matches!(&e, matedit::Error::File { path: p, .. } if p == path),
                "not an error naming {}: {m:?}",
                path.display()
            );
            assert!(!m.contains(['\n', '\r']), "more than one line: {m:?}");
            None
        }
    }
}

/// [`clean`] for the parsers whose errors are messages that their `read` turns into an
/// [`matedit::Error::File`] for the file, as here.
pub fn clean_message<T>(path: &Path, r: Result<T, String>) -> Option<T> {
    clean(path, r.map_err(|m| matedit::Error::file(path, m)))
}
