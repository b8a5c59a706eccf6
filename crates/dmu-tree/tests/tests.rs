mod hard_cases;
mod queries;
mod support;
