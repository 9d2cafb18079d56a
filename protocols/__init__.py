"""Node behaviours (protocols) built on aquasim_py."""
