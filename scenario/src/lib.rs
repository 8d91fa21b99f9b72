//! The scenario a DUPAC process flies, set up once and shared by the commands, the evaluation
//! and the Python package: the radio world and its RSRP source ([`world`]), the planners
//! ([`planners`]), the held-out splits, the training pool and each pair's guide path
//! ([`pairs`]), the guide paths kept on disk per host ([`guide_cache`]), and the progress bars
//! and stage clock of that preparation ([`progress`]). Over the simulation (`dupac-actor`) and
//! the radio; below `dupac-run`, `dupac-eval` and `dupac-py`.

pub mod error;
pub mod guide_cache;
pub mod pairs;
pub mod planners;
pub mod progress;
pub mod world;
