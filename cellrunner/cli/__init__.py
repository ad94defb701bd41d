"""cellrunner.cli"""
