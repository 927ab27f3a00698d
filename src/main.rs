//! Placeholder: the embassy firmware binary.
#![no_std]
#![no_main]
