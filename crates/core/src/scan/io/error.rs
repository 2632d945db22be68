//! Why a point cloud file cannot be read.

/// Why a file holds no readable cloud.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FormatError {
    #[error("cannot read {0}")]
    Io(String),
    #[error("not a valid {format} file: {reason}")]
    Parse {
        format: &'static str,
        reason: String,
    },
    #[error("the {format} file has no `{what}`")]
    Missing {
        format: &'static str,
        what: &'static str,
    },
    #[error("the file has {got} points, more than the limit of {max}")]
    TooMany { got: u64, max: usize },
    #[error("the cloud cannot be written: {0}")]
    Invalid(String),
    #[error("unknown point cloud format `{0}`: use .ply, .pcd, .las, .laz or .xyz")]
    UnknownFormat(String),
}
