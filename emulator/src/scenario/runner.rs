//! Offline scenario runner (phase 2).
