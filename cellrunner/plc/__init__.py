"""cellrunner.plc"""
