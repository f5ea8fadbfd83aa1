//! Datasets: from scenes to episodes, splits and files.
