//! Where one skill hands over to the next: the states a controller delivers a skill
//! ([`deliver`]), fine-tuning a skill inside the controller's episodes ([`refine`]), when the
//! terminal skill will succeed ([`readiness`]), and distilling a search into a controller
//! ([`distill`]).

pub mod deliver;
pub mod distill;
pub mod readiness;
pub mod refine;
