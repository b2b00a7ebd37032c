//! The crate's error type: every failure the user can cause is an [`Error`]
//! with a message that names the file, mesh, key or device involved.

use std::path::PathBuf;

/// Everything that can go wrong in the library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file or folder that could not be read or written.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A glTF file could not be loaded or holds invalid geometry.
    #[error("{path}: {message}")]
    Gltf {
        /// The glTF (`.gltf` or `.glb`) file read or written.
        path: PathBuf,
        /// What went wrong, naming the mesh, node or light where there is
        /// one.
        message: String,
    },
    /// A scene file (TOML) is malformed or has an invalid value.
    #[error("{path}: {message}")]
    SceneFile {
        /// The `.toml` scene file.
        path: PathBuf,
        /// What is wrong, naming the key (and line, for a parse error).
        message: String,
    },
    /// An invalid argument or value given through the API or the CLI.
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// A Vulkan call failed or the device cannot do what is asked.
    #[error("vulkan: {0}")]
    Vulkan(String),
    /// The Khronos validation layer reported an error.
    #[error("vulkan validation error: {0}")]
    Validation(String),
    /// Writing an image or dump failed.
    #[error("image: {0}")]
    Image(String),
}

/// Shorthand for `Result<T, alias_free_shadows::Error>`.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An [`Error::Io`] for `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}

impl From<ash::vk::Result> for Error {
    fn from(r: ash::vk::Result) -> Self {
        Error::Vulkan(format!("{r:?}"))
    }
}
