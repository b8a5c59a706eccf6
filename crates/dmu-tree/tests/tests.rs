mod changes;
mod exact_picks;
mod hard_cases;
mod overlap;
mod queries;
mod support;
