//! Why a query shape was refused: every shape checks its numbers when it is
//! made, so the tests on it never see a NaN or an inverted camera.

/// A query shape with numbers that describe no shape.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ShapeError {
    /// A number of the shape is NaN or infinite.
    #[error("{what} must be finite")]
    NotFinite {
        /// What the shape is.
        what: &'static str,
    },
    /// The numbers are finite but describe no shape (a zero direction, a
    /// negative length, a viewport of 0 pixels).
    #[error("{what}: {detail}")]
    Invalid {
        /// What the shape is.
        what: &'static str,
        /// What is wrong.
        detail: String,
    },
}
