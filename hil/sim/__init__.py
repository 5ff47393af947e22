"""The simulation engine, with no family names: models plug into a scan engine; servers run on a loop thread;
wire faults perturb what a server sends.  A family brings its memory, models and protocol servers."""
