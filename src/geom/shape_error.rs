//! Why a query shape was refused: every shape checks its numbers when it is
//! made, so the tests on it never see a NaN or an inverted camera.

/// A query shape with numbers that describe no shape.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ShapeError {
    #[error("{what} must be finite")]
    NotFinite { what: &'static str },
    #[error("{what}: {detail}")]
    Invalid { what: &'static str, detail: String },
}
