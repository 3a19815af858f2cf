//! The point indexes the stages query.

mod neighbours;

pub use neighbours::Neighbours;
