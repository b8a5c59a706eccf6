mod changes;
mod hard_cases;
mod overlap;
mod queries;
mod support;
