"""kapsel.analysis"""
