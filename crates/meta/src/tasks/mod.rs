//! The tasks beyond sitting: the warehouse's phases ([`warehouse`]), the toss ([`toss`]) and
//! their evaluations ([`task_eval`]).

pub mod task_eval;
pub mod toss;
pub mod warehouse;
