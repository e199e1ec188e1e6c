//! Searching in copies of the episode: the planner that simulates skill plans
//! ([`planner`]) and the trained controller's lookahead ([`lookahead`]).

pub mod lookahead;
pub mod planner;
