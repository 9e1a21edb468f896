"""The co-simulation master: FMU adapters, connection graph, sources and the stepping loop."""
