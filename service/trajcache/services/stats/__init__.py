"""Plan statistics: events, hourly rollups, histograms and windows."""
