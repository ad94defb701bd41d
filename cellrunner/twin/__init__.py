"""cellrunner.twin"""
