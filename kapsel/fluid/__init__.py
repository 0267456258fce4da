"""kapsel.fluid"""
