"""kapsel.io"""
