//! GPU rendering (wgpu): arrives with the app issue.
