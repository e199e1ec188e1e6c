//! Motion-capture clip formats (BVH, ASF/AMC, DeepMimic JSON).
