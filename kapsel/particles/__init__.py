"""kapsel.particles"""
