//! Where an OBJ's companion files come from: the disk, or memory (tests and fuzzers).

use std::path::Path;

/// Where an OBJ's companion files (its MTL libraries and the texture maps they name) come
/// from: the disk ([`Disk`]), or memory for tests and fuzzers (any
/// `Fn(&Path) -> Option<Vec<u8>>`, `None` meaning "no such file").
pub trait FileSource {
    /// The bytes of the file at `path`.
    ///
    /// # Errors
    /// When the file does not exist (kind `NotFound`) or cannot be read.
    fn read(&self, path: &Path) -> std::io::Result<Vec<u8>>;
    /// Whether `path` is an existing regular file.
    fn is_file(&self, path: &Path) -> bool;
}

/// Companion files read from the file system.
#[derive(Clone, Copy, Debug, Default)]
pub struct Disk;

impl FileSource for Disk {
    fn read(&self, path: &Path) -> std::io::Result<Vec<u8>> {
        std::fs::read(path)
    }
    fn is_file(&self, path: &Path) -> bool {
        path.is_file()
    }
}

impl<F: Fn(&Path) -> Option<Vec<u8>>> FileSource for F {
    fn read(&self, path: &Path) -> std::io::Result<Vec<u8>> {
        self(path).ok_or_else(|| std::io::Error::from(std::io::ErrorKind::NotFound))
    }
    fn is_file(&self, path: &Path) -> bool {
        self(path).is_some()
    }
}
