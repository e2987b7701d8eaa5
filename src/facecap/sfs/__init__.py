"""Fine detail from video by space-time shape from shading (Lo et al.)."""
