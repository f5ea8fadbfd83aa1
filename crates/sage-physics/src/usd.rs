//! USDA export.
